"""Manual overrides: an instructor sets one item's score on one submission, with a required comment.

The one place an override reaches a score is `overridden_report`, and the one place it is stored is `set_override`:
it keeps the Override row (a later one supersedes it, both kept) and stores a new current Grade whose report
carries the override, superseding the grade it overrode (grader.core.grades.grade_history keeps both). Every reader
reads the current grade (the visibility rule grader.services.submissions.visibility, the counted scores, the dashboard, the CSV
and Gradescope exports, the API), so each uses the override without a second rule. A regrade applies the current
overrides to its new grade the same way (grader.services.rubrics.regrade).

An overridden item keeps what was measured: its `verdict`, `measured_score` and `measured_max_score` beside the
`override` {score, comment, by, at}; its `score` is the override and it counts its full points (even an inconclusive
one, which the measurement alone left uncounted).
"""

from __future__ import annotations

import math
from datetime import datetime

from pydantic import BaseModel
from sqlalchemy import select
from sqlalchemy.orm import Session

from grader.core.lifecycle import lock_submission
from grader.core.overrides import current_overrides, measured_item, overridden_report  # noqa: F401 (re-exported)
from grader.core.lti_outbox import scores_changed
from grader.core.grades import current_grade
from grader.core.models import Grade, Override, Submission, User, utcnow
from grader.core.schemas import UtcDateTime
from grader.services.identity.access import require_instructor
from grader.services.errors import Conflict, Invalid, NotFound

MAX_COMMENT = 2000


class OverridePublic(BaseModel):
    id: int
    submission_id: int
    item_id: str
    score: float
    comment: str
    by: str
    at: UtcDateTime
    # The item as measured under the grade's current rubric version (a regrade measures it again) while the override
    # is in force; a superseded override keeps what its own grade measured.
    measured_score: float | None
    measured_verdict: str | None
    measured_rubric_version: str | None
    current: bool
    superseded_at: UtcDateTime | None


# the one rule (measured_item, overridden_item, overridden_report, current_overrides) is in grader.core.overrides

def override_history(session: Session, submission_id: int) -> list[Override]:
    """Every override a submission ever had, oldest first (superseded ones kept)."""
    return list(session.scalars(select(Override).where(Override.submission_id == submission_id)
                                .order_by(Override.id)))


def recent_overrides(session: Session, *, course_id: int, limit: int = 10) -> list[Override]:
    """The course's newest overrides in force, newest first (the dashboard's list)."""
    return list(session.scalars(select(Override).join(Submission, Override.submission_id == Submission.id)
                                .where(Submission.course_id == course_id, Override.superseded_at.is_(None))
                                .order_by(Override.at.desc(), Override.id.desc()).limit(limit)))


def public(session: Session, override: Override) -> OverridePublic:
    """An override with the item as measured beside it: under the submission's current grade while the override is in
    force (after a regrade, the new version's measurement, not the one it first overrode), else under its own grade."""
    grade = _measured_in(session, override)
    measured = _measured_of(grade, override.item_id)
    return OverridePublic(id=override.id, submission_id=override.submission_id, item_id=override.item_id,
                          score=override.score, comment=override.comment, by=override.by.name, at=override.at,
                          measured_score=measured.get("score"), measured_verdict=measured.get("verdict"),
                          measured_rubric_version=grade.rubric_version if measured else None,
                          current=override.superseded_at is None, superseded_at=override.superseded_at)


def _measured_in(session: Session, override: Override) -> Grade | None:
    """The grade whose measurement an override is shown beside: the current one for an override in force (every
    grade stored since carries it, grader.core.overrides), else the grade the override itself stored."""
    if override.superseded_at is None and (grade := current_grade(session, override.submission_id)) is not None:
        return grade
    return session.get(Grade, override.grade_id) if override.grade_id else None


def _measured_of(grade: Grade | None, item_id: str) -> dict:
    item = next((i for i in (grade.report if grade else {}).get("items", []) if i["id"] == item_id), None)
    return measured_item(item) if item else {}


# --- writing -------------------------------------------------------------------------------------------------------

def check_override(report: dict, *, item_id: str, score: float | None, comment: str) -> list[dict[str, str]]:
    """Every rule the request breaks, each naming its field: an item of this grade, a score from 0 to the item's
    points, a comment that says why (required, at most MAX_COMMENT characters)."""
    errors = []
    items = {i["id"]: i for i in report.get("items", [])}
    item = items.get(item_id)
    if item is None:
        errors.append({"field": "item_id", "rule": f"must be an item of this grade ({', '.join(items)})"})
    if score is None or not isinstance(score, int | float) or isinstance(score, bool) or not math.isfinite(score):
        errors.append({"field": "score", "rule": "required: a number of points"})
    elif item is not None and not 0 <= score <= item["points"]:
        errors.append({"field": "score", "rule": f"must be from 0 to {item['points']:g}, item {item_id}'s points"})
    elif item is None and score < 0:
        errors.append({"field": "score", "rule": "must be at least 0"})
    text = (comment or "").strip()
    if not text:
        errors.append({"field": "comment", "rule": "required: say why the score is overridden (the student reads it)"})
    elif len(text) > MAX_COMMENT:
        errors.append({"field": "comment", "rule": f"at most {MAX_COMMENT} characters (this one has {len(text)})"})
    return errors


def set_override(*, session: Session, submission: Submission, user: User, item_id: str, score: float | None,
                 comment: str, now: datetime | None = None, commit: bool = True) -> Override:
    """An instructor of the submission's course overrides one item's score (see the module's docstring).

    NotFound for another course's submission, Forbidden for anyone but an instructor, Conflict while it has no grade
    or its lab check is still being evaluated, Invalid naming each field and rule; nothing is stored then.
    Commits unless `commit` is False (a review request's answer stores its override in its own transaction)."""
    if submission.course_id != user.course_id:
        raise NotFound(f"submission {submission.id} not found")
    require_instructor(user, action="override a score")
    lock_submission(session, submission.id)  # two overrides, or an override and a regrade, serialize here
    grade = current_grade(session, submission.id)
    if grade is None:
        raise Conflict(f"submission {submission.id} is {submission.status}, not graded: nothing to override")
    if grade.completed_at is None:
        raise Conflict(f"submission {submission.id}'s lab check is still being evaluated; override once "
                       "it is (seconds)")
    errors = check_override(grade.report, item_id=item_id, score=score, comment=comment)
    if errors:
        raise Invalid("invalid override", errors)
    now = now or utcnow()
    override = Override(submission_id=submission.id, item_id=item_id, score=float(score), comment=comment.strip(),
                        by_id=user.id, by=user, at=now)
    previous = session.scalar(select(Override).where(Override.submission_id == submission.id,
                                                     Override.item_id == item_id, Override.superseded_at.is_(None)))
    if previous is not None:
        previous.superseded_at = now
        session.flush()  # the old override stops being current before the new one is
    session.add(override)
    session.flush()
    if previous is not None:
        previous.superseded_by_id = override.id
    override.grade_id = _store_overridden(session, grade, current_overrides(session, submission.id), override,
                                          now).id
    if submission.assignment_id is not None:  # its counted score goes to the LMS gradebooks, marked in this transaction
        scores_changed(session=session, assignment=submission.assignment)
    if commit:
        session.commit()
    return override


def _store_overridden(session: Session, grade: Grade, overrides: list[Override], made_by: Override,
                      now: datetime) -> Grade:
    """A new current grade: `grade`'s report with `overrides` applied; `grade` is superseded and kept."""
    report = overridden_report(grade.report, overrides)
    report["made_by_override"] = {"item_id": made_by.item_id, "by": made_by.by.name}
    grade.superseded_at = now
    session.flush()  # the one-current-grade index: the old grade stops being current first
    new = Grade(submission_id=grade.submission_id, rubric_lesson=grade.rubric_lesson,
                rubric_version=grade.rubric_version, rubric_hash=grade.rubric_hash, total=report["total"],
                max_total=report["max_total"], report=report, execution_s=grade.execution_s, created_at=now,
                completed_at=now)
    session.add(new)
    session.flush()
    return new
