"""Grade a submission once its last case run finished, in two tasks (worker.tasks):

1. `grade_submission`: the rubric engine on the stored measurements; the grade (scores, verdicts, feedback) is
   stored and the submission is 'graded' as soon as it has run (about 0.3 s for L03);
2. `complete_grade`: the lab check (L03 CHECK line) on the submission's own runs, added to the stored grade, which
   is then complete. A student reads the score meanwhile and the report page says the check is coming. Its task
   waits on the cpu queue behind every case run (the lowest priority), so at a deadline the grades come first.

Nothing is drawn here: the report's charts are drawn in the reader's browser from the arrays stored in the
database (grader/services/reports/series.py), so any API host shows them and a report is complete right after its
cases. Drawing them as 18 PNGs cost more CPU than the simulation (docs/benchmark.md, issue 24); the PNGs
(worker/figures) remain for the command line's offline report (`grader check`).

Both are idempotent: a re-sent grade task (a worker killed while completing; the reconciler re-sends it for a grade
left incomplete) completes what is missing and never grades twice. State changes go through
grader.core.lifecycle.
"""

from __future__ import annotations

from sqlalchemy import update
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from grader.core.lab_check import lab_check
from grader.core.grading import grade_and_store
from grader.core.lifecycle import stored_result, touch
from grader.core.rubrics import course_rubric
from grader.core.grades import current_grade
from grader.core.models import Event, Grade, Submission, utcnow
from grader.core.settings import settings
from grader.core.states import SubmissionState
from grader.core.variants import record_check, record_failure, submission_variant


def grade_submission(*, session: Session, submission_id: int) -> Grade | None:
    """Grade a submission in state 'grading' exactly once; None if it is not (or no longer) waiting for a grade.

    The grade is stored without its lab check (completed_at NULL): `complete_grade` adds it."""
    submission = session.get(Submission, submission_id)
    if submission is None or submission.status != SubmissionState.GRADING:
        return None
    existing = current_grade(session, submission_id)
    if existing is not None:  # graded before a crash could record the state change
        touch(submission, SubmissionState.GRADED, "grade already stored", session=session)
        session.commit()
        return existing
    try:
        book = course_rubric(session, submission.course_id, submission.lesson)
        grade = grade_and_store(session=session, submission=submission, book=book, complete=False,
                                detail="lab check next")
    except Exception as exc:  # a grading bug must be visible on the submission, not a stuck 'grading'
        session.rollback()
        submission = session.get(Submission, submission_id)
        submission.error = f"grading failed: {type(exc).__name__}: {exc}"
        touch(submission, SubmissionState.FAILED, submission.error, session=session)
        record_failure(session, submission, submission.error)  # a pool variant it measures is dropped, saying why
        session.commit()
        return None
    try:
        session.commit()
    except IntegrityError:  # another grader won the race; its grade stands
        session.rollback()
        return None
    return grade


def complete_grade(*, session: Session, submission_id: int) -> Grade | None:
    """Add the lab check to a submission's current grade, once; None when there is nothing to complete (no grade,
    or complete already).

    Nothing is locked while the check is evaluated (a write lock would stop every other writer of an SQLite
    database): two completions of one grade evaluate the same runs, and only the first to store its check wins.
    """
    submission = session.get(Submission, submission_id)
    grade = current_grade(session, submission_id)
    if submission is None or grade is None or grade.completed_at is not None:
        return None
    check, check_note = _check(submission, course_rubric(session, submission.course_id, submission.lesson))
    report = {**grade.report, "check": check.model_dump(mode="json") if check is not None else None}
    stored = session.execute(update(Grade).where(Grade.id == grade.id, Grade.completed_at.is_(None))
                             .values(report=report, completed_at=utcnow())).rowcount == 1
    if not stored:  # completed meanwhile by a duplicate delivery of the grade task
        session.rollback()
        return None
    session.add(Event(submission_id=submission.id, state="lab-check", detail=check_note))
    record_check(session, submission, check, check_note)  # a pool variant it measures is kept or dropped on it
    session.commit()
    session.refresh(grade)
    return grade


def _check(submission: Submission, book) -> tuple:
    """(the lab check or None, the check's event note). Never raises for what a re-sent task could not mend either:
    runs unreadable since grading are recorded as such."""
    try:
        results = {run.name: stored_result(run) for run in submission.case_runs}
    except Exception as exc:  # noqa: BLE001 - recorded in the event; the grade stands and is complete
        return None, f"lab check failed: runs unreadable: {type(exc).__name__}: {exc}"
    reused = {run.name: run.reused_from_id for run in submission.case_runs if run.reused_from_id}
    return lab_check(results, rubric=book, reused=reused, artifacts_dir=settings.artifacts_dir,
                     variant=submission_variant(submission))
