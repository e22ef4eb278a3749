"""The one door to the rubric engine: parse a sheet, list its cases, grade it on stored measurements.

Everything the service knows about sheets and rubrics goes through these functions, so the rubric package's
API can change in one place.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

from sqlalchemy import select
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from grader import crud
from grader.models import CaseRun, Grade, Submission, utcnow


def parse_sheet(data: dict[str, Any]):
    """The validated sheet; raises pydantic.ValidationError naming each bad item."""
    import rubric

    return rubric.parse_sheet(data)


def cases_to_run(sheet) -> list:
    import rubric

    return list(rubric.cases_to_run(sheet))


def stored_result(run: CaseRun):
    """The CaseResult a case run stands for, read back from its stored provenance and .npz arrays."""
    import numpy as np

    from rubric import CaseResult, Provenance, parse_case
    from rubric.metrics import parse_metrics

    spec = parse_case(run.spec)
    provenance = Provenance.model_validate(run.provenance) if run.provenance else None
    if run.status != "done" or run.result_status != "ok":
        return CaseResult(spec=spec, status=run.result_status or "failed", provenance=provenance,
                          error=run.error or f"case run ended {run.status}", out_dir=run.artifact_dir)
    with np.load(Path(run.artifact_dir) / "arrays.npz", allow_pickle=False) as npz:
        arrays = {name: npz[name] for name in npz.files}
    metrics = parse_metrics(run.metrics) if run.metrics else None
    return CaseResult(spec=spec, status="ok", arrays=arrays, provenance=provenance, metrics=metrics,
                      out_dir=run.artifact_dir, wall_s=run.wall_s or 0.0)


def grade_submission(*, session: Session, submission_id: int) -> Grade | None:
    """Grade a submission in state 'grading' exactly once; None if it is not (or no longer) waiting for a grade."""
    import rubric

    submission = session.get(Submission, submission_id)
    if submission is None or submission.status != "grading":
        return None
    existing = session.scalar(select(Grade).where(Grade.submission_id == submission_id))
    if existing is not None:  # graded before a crash could record the state change
        crud.touch(submission, "graded", "grade already stored", session=session)
        session.commit()
        return existing
    started = time.perf_counter()
    try:
        sheet = parse_sheet(submission.sheet)
        results = {run.name: stored_result(run) for run in submission.case_runs}
        book = rubric.load_rubric(lesson=submission.lesson)
        report = rubric.grade_sheet(sheet, results, book)
    except Exception as exc:  # a grading bug must be visible on the submission, not a stuck 'grading'
        submission.error = f"grading failed: {type(exc).__name__}: {exc}"
        crud.touch(submission, "failed", submission.error, session=session)
        session.commit()
        return None
    grade = Grade(submission_id=submission.id, rubric_lesson=book.lesson, rubric_version=str(book.version),
                  rubric_hash=book.content_hash, total=report.total, max_total=report.max_total,
                  report=report.model_dump(mode="json"), execution_s=time.perf_counter() - started)
    session.add(grade)
    submission.graded_at = utcnow()
    crud.touch(submission, "graded", f"{report.total:g} / {report.max_total:g}", session=session)
    try:
        session.commit()
    except IntegrityError:  # another grader won the race; its grade stands
        session.rollback()
        return None
    return grade
