"""Grade a submission once its last case run finished: the rubric engine on the stored measurements.

The worker-side body of the `grade_submission` task; state changes go through grader.core.lifecycle.
"""

from __future__ import annotations

import time

from sqlalchemy import select
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from grader.core.lifecycle import stored_result, touch
from grader.models import Grade, Submission, utcnow


def grade_submission(*, session: Session, submission_id: int) -> Grade | None:
    """Grade a submission in state 'grading' exactly once; None if it is not (or no longer) waiting for a grade."""
    import rubric

    submission = session.get(Submission, submission_id)
    if submission is None or submission.status != "grading":
        return None
    existing = session.scalar(select(Grade).where(Grade.submission_id == submission_id))
    if existing is not None:  # graded before a crash could record the state change
        touch(submission, "graded", "grade already stored", session=session)
        session.commit()
        return existing
    started = time.perf_counter()
    try:
        sheet = rubric.parse_sheet(submission.sheet)
        results = {run.name: stored_result(run) for run in submission.case_runs}
        book = rubric.load_rubric(lesson=submission.lesson)
        report = rubric.grade_sheet(sheet, results, book)
    except Exception as exc:  # a grading bug must be visible on the submission, not a stuck 'grading'
        submission.error = f"grading failed: {type(exc).__name__}: {exc}"
        touch(submission, "failed", submission.error, session=session)
        session.commit()
        return None
    grade = Grade(submission_id=submission.id, rubric_lesson=book.lesson, rubric_version=str(book.version),
                  rubric_hash=book.content_hash, total=report.total, max_total=report.max_total,
                  report=report.model_dump(mode="json"), execution_s=time.perf_counter() - started)
    session.add(grade)
    submission.graded_at = utcnow()
    touch(submission, "graded", f"{report.total:g} / {report.max_total:g}", session=session)
    try:
        session.commit()
    except IntegrityError:  # another grader won the race; its grade stands
        session.rollback()
        return None
    return grade
