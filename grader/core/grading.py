"""Grading a submission under a rubric version and storing the grade: the one place it happens.

Used by the worker's grade task (worker.grading), a checkpoint sheet graded when it is submitted
(grader.services.submissions.submit) and a committed regrade (grader.services.rubrics.regrade). Scoring reads only the stored
measurements of the submission's case runs (`lifecycle.stored_result`); nothing here runs a case or draws.
"""

from __future__ import annotations

import time
from datetime import datetime

from sqlalchemy.orm import Session

import rubric
from grader.core.lifecycle import stored_result, touch
from grader.core.lti_outbox import scores_changed
from grader.core.overrides import current_overrides, overridden_report
from grader.core.grades import current_grade
from grader.core.states import SubmissionState
from grader.core.models import Grade, Regrade, Submission, utcnow
from grader.core.variants import submission_variant, try_flag_copying


def score(submission: Submission, book) -> rubric.GradeReport:
    """The submission's sheet scored under rubric version `book` on its stored measurements (raises on a bug), under
    its variant where it has one (grader.core.variants: an assignment's pool; a regrade keeps it too)."""
    sheet = rubric.parse_sheet(submission.sheet, submission.part)
    results = {run.name: stored_result(run) for run in submission.case_runs}
    return rubric.grade_sheet(sheet, results, book, submission_variant(submission))


def store_grade(*, session: Session, submission: Submission, book, report: rubric.GradeReport, execution_s: float,
                complete: bool, regrade: Regrade | None = None, now: datetime | None = None,
                detail: str | None = None) -> Grade:
    """Store `report` as the submission's current grade (no commit). `complete`: its lab check is evaluated already or
    not wanted (a checkpoint set, or a regrade that evaluated the check again); otherwise `completed_at` stays empty
    until worker.grading.complete_grade adds the check. A regrade's grade supersedes the current one, kept in the history;
    any other grading moves the submission to graded with an event naming the rubric version and `detail`: never the
    scores, which a student may not be shown yet (grader.services.submissions.visibility)."""
    now = now or utcnow()
    if regrade is not None:
        current = current_grade(session, submission.id, report=False)
        if current is not None:
            current.superseded_at = now
            session.flush()  # the old grade stops being current before the new one becomes current
    stored = report.model_dump(mode="json")
    overrides = current_overrides(session, submission.id) if regrade is None else []
    if overrides:  # graded again (a re-sent case run): an instructor's scores stay in force (a regrade applies its own)
        stored = overridden_report(stored, overrides)
    grade = Grade(submission_id=submission.id, rubric_lesson=book.lesson, rubric_version=str(book.version),
                  rubric_hash=book.content_hash, total=stored["total"], max_total=stored["max_total"],
                  report=stored, execution_s=execution_s, created_at=now,
                  regrade_id=regrade.id if regrade is not None else None, completed_at=now if complete else None)
    session.add(grade)
    if regrade is None:
        submission.graded_at = now
        touch(submission, SubmissionState.GRADED,
              f"graded under rubric {book.lesson} v{book.version}" + (f"; {detail}" if detail else ""), session=session)
    if submission.assignment_id is not None:  # its counted score goes to the LMS gradebooks, marked in this transaction
        scores_changed(session=session, assignment=submission.assignment)
    return grade


def grade_and_store(*, session: Session, submission: Submission, book, complete: bool,
                    detail: str | None = None) -> Grade:
    """Score the submission under `book` and store the grade (no commit); see `score` and `store_grade`. A variant
    sheet's copy evidence is stored beside it (grader.core.variants.try_flag_copying), never changing it."""
    started = time.perf_counter()
    report = score(submission, book)
    grade = store_grade(session=session, submission=submission, book=book, report=report,
                        execution_s=time.perf_counter() - started, complete=complete, detail=detail)
    if submission.variant_id is not None:
        session.flush()  # the grade's id, which the evidence names
        try_flag_copying(session, submission, grade, report, book)
    return grade
