"""A submission's grades: the one that counts (not superseded by a regrade) and every one it ever had. Grades are
stored by grader.core.grading; a regrade supersedes one (grader.services.rubrics.regrade)."""

from __future__ import annotations

from sqlalchemy import select
from sqlalchemy.orm import Session, defer

from grader.core.models import Grade


def current_grade(session: Session, submission_id: int, *, report: bool = True) -> Grade | None:
    """The submission's grade that counts (the newest not superseded by a regrade), or None. `report=False` leaves
    its report (the largest JSON stored) to be loaded only if read: decoding it was a third of an API read."""
    query = select(Grade).where(Grade.submission_id == submission_id, Grade.superseded_at.is_(None))
    return session.scalar(query if report else query.options(defer(Grade.report)))


def grade_history(session: Session, submission_id: int) -> list[Grade]:
    """Every grade a submission ever had, oldest first; the last one is the current one."""
    return list(session.scalars(select(Grade).where(Grade.submission_id == submission_id).order_by(Grade.id)
                                .options(defer(Grade.report))))  # totals and dates: the reports load only if read
