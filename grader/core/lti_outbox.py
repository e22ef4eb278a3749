"""Marking an assignment's counted scores as changed for the LMS gradebooks, in the change's own transaction.

The neutral core holds this half of grader.services.lti.outbox so that grading (grader.core.grading.store_grade,
called by the worker and by a regrade) can mark without importing a service; sending is the service's half."""

from __future__ import annotations

from datetime import datetime

from sqlalchemy import case, exists, select
from sqlalchemy.dialects import postgresql, sqlite
from sqlalchemy.orm import Session

from grader.core.models import Assignment, Course, LtiContext, LtiLineItem, LtiOutbox, LtiRegistration, utcnow


def _has_gradebook(session: Session, course_id: int) -> bool:
    """Whether any LMS course of this course gave a grades service (its line items, or a link's own line item):
    otherwise there is nothing to send anywhere."""
    link_item = exists().where(LtiLineItem.context_id == LtiContext.id)
    return bool(session.scalar(select(exists().where(LtiContext.registration_id == LtiRegistration.id,
                                                     LtiRegistration.course_id == course_id,
                                                     LtiContext.lineitems_url.is_not(None) | link_item))))


def mark(*, session: Session, assignment_ids: list[int], now: datetime | None = None) -> None:
    """Due now for the next pass: one upsert per assignment (two transactions marking one assignment never collide).
    An assignment backing off after failed sends keeps its retry time: the retry sends the newest scores anyway, and
    a burst of grades must not hammer a platform that is down. No commit: the caller's change commits it."""
    now = now or utcnow()
    if not assignment_ids:
        return
    dialect = postgresql if session.get_bind().dialect.name == "postgresql" else sqlite
    table = LtiOutbox.__table__
    for assignment_id in sorted(set(assignment_ids)):
        statement = dialect.insert(table).values(assignment_id=assignment_id, changed_at=now, due_at=now, attempts=0)
        backing_off = (table.c.attempts > 0) & (table.c.due_at > now)
        session.execute(statement.on_conflict_do_update(index_elements=[table.c.assignment_id], set_={
            "changed_at": now, "due_at": case((backing_off, table.c.due_at), else_=now)}))


def scores_changed(*, session: Session, assignment: Assignment | None = None, course: Course | None = None) -> None:
    """The counted scores of `assignment` (or of every assignment of `course`) may have changed: grading, a release,
    an override, a regrade. Marks them for the LMS gradebooks where the course has one; no commit."""
    course_id = assignment.course_id if assignment is not None else course.id
    if not _has_gradebook(session, course_id):
        return
    ids = ([assignment.id] if assignment is not None
           else list(session.scalars(select(Assignment.id).where(Assignment.course_id == course_id))))
    mark(session=session, assignment_ids=ids)
