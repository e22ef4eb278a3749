"""Grade a submission once its last case run finished: the rubric engine on the stored measurements, then the
lab figures drawn from the same results (never inside an API request), then the lab check (L03 CHECK line) on the
submission's own runs, stored with the grade.

The worker-side body of the `grade_submission` task; state changes go through grader.core.lifecycle.
"""

from __future__ import annotations

import time

from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from grader.core.lab_check import lab_check
from grader.core.lifecycle import stored_result, touch
from grader.core.rubrics import course_rubric, current_grade
from grader.models import Event, Grade, Submission, utcnow
from grader.settings import settings


def grade_submission(*, session: Session, submission_id: int) -> Grade | None:
    """Grade a submission in state 'grading' exactly once; None if it is not (or no longer) waiting for a grade."""
    import rubric

    submission = session.get(Submission, submission_id)
    if submission is None or submission.status != "grading":
        return None
    existing = current_grade(session, submission_id)
    if existing is not None:  # graded before a crash could record the state change
        touch(submission, "graded", "grade already stored", session=session)
        session.commit()
        return existing
    started = time.perf_counter()
    try:
        sheet = rubric.parse_sheet(submission.sheet, submission.items)
        results = {run.name: stored_result(run) for run in submission.case_runs}
        book = course_rubric(session, submission.course_id, submission.lesson)
        report = rubric.grade_sheet(sheet, results, book)
    except Exception as exc:  # a grading bug must be visible on the submission, not a stuck 'grading'
        submission.error = f"grading failed: {type(exc).__name__}: {exc}"
        touch(submission, "failed", submission.error, session=session)
        session.commit()
        return None
    execution_s = time.perf_counter() - started  # grading itself; drawing the figures is not part of it
    figures_note, figures = draw_figures(submission.id, results)
    reused = {run.name: run.reused_from_id for run in submission.case_runs if run.reused_from_id}
    check, check_note = lab_check(results, figures=figures, rubric=book, reused=reused,
                                  artifacts_dir=settings.artifacts_dir)
    report = report.model_copy(update={"check": check})
    grade = Grade(submission_id=submission.id, rubric_lesson=book.lesson, rubric_version=str(book.version),
                  rubric_hash=book.content_hash, total=report.total, max_total=report.max_total,
                  report=report.model_dump(mode="json"), execution_s=execution_s)
    session.add(grade)
    submission.graded_at = utcnow()
    session.add(Event(submission_id=submission.id, state="figures", detail=figures_note))
    session.add(Event(submission_id=submission.id, state="lab-check", detail=check_note))
    touch(submission, "graded", f"{report.total:g} / {report.max_total:g}", session=session)
    try:
        session.commit()
    except IntegrityError:  # another grader won the race; its grade stands
        session.rollback()
        return None
    return grade


def draw_figures(submission_id: int, results: dict) -> tuple[str, list]:
    """The lab figures of a submission's results, drawn before its grade is stored so a graded submission has them.

    Failed case runs are passed too, so each figure names what it could not draw. A drawing failure never blocks
    or changes the grade: it is recorded (the returned note becomes an event) and the pages show no figures.
    Returns the note and the paths drawn.
    """
    from worker.figures import FigureCache, lab_figures

    folder = settings.figures_dir(submission_id)
    cache = FigureCache(settings.artifacts_dir / "figure-cache")
    started = time.perf_counter()
    try:
        paths = lab_figures(results, folder, cache=cache)
    except Exception as exc:  # noqa: BLE001 - the evidence of a drawing bug is the event, the grade stands
        return f"figures failed: {type(exc).__name__}: {exc}", []
    return (f"{len(paths)} figures in {folder} ({cache.drawn} drawn, {cache.copied} copied from the figure cache: "
            f"same runs, same drawing code) in {time.perf_counter() - started:.2f} s"), paths
