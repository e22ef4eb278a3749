"""The record of a course's set-up changes: who changed what and when. The services that make a change (courses,
assignments, roster, sign_in_links) add its row in the same transaction as the change itself, so a change made from a
page, the API or the command line is recorded alike, and a refused change records nothing."""

from __future__ import annotations

from enum import StrEnum
from typing import Any

from sqlalchemy import select
from sqlalchemy.orm import Session

from grader.core.models import Assignment, Course, CourseChange, User

SHOWN = 200  # the newest changes a page lists


class ChangeKind(StrEnum):
    COURSE_SETTINGS = "course_settings"
    ASSIGNMENT_CREATED = "assignment_created"
    ASSIGNMENT_EDITED = "assignment_edited"
    RELEASED = "released"
    EXTENSION_GRANTED = "extension_granted"
    EXTENSION_REVOKED = "extension_revoked"
    ROSTER_IMPORTED = "roster_imported"
    SIGN_IN_LINK_ISSUED = "sign_in_link_issued"


def record(*, session: Session, course: Course, by: User, kind: ChangeKind, summary: str,
           detail: dict[str, Any] | None = None, assignment: Assignment | None = None) -> CourseChange:
    """Add one change to the course's record; the caller commits it with the change (never a secret in `detail`)."""
    row = CourseChange(course_id=course.id, by_id=by.id, kind=kind, summary=summary, detail=detail or {},
                       assignment_id=assignment.id if assignment is not None else None)
    session.add(row)
    return row


def of_course(*, session: Session, course: Course, assignment: Assignment | None = None,
              limit: int = SHOWN) -> list[CourseChange]:
    """The course's newest changes first (only one assignment's, when given)."""
    query = select(CourseChange).where(CourseChange.course_id == course.id)
    if assignment is not None:
        query = query.where(CourseChange.assignment_id == assignment.id)
    return list(session.scalars(query.order_by(CourseChange.id.desc()).limit(limit)))
