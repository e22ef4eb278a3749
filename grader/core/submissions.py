"""Storing a new submission with one queued case run per spec: the one home of it for the submit service and for a
variant pool drawn further by the worker (grader.core.variants.continue_pool), which may import only the core."""

from __future__ import annotations

from typing import Any

from sqlalchemy.orm import Session

from grader.core.audit import spec_key
from grader.core.models import CaseRun, Event, Submission, User
from grader.core.states import CaseRunState


def create_submission(
    *, session: Session, student: User, lesson: str, sheet: dict[str, Any], specs: list, force_rerun: bool
) -> Submission:
    """The submission and one queued CaseRun per spec, added to the session (commit before enqueueing)."""
    submission = Submission(
        course_id=student.course_id, student_id=student.id, lesson=lesson, sheet=sheet, force_rerun=force_rerun
    )
    session.add(submission)
    session.flush()
    session.add(Event(submission_id=submission.id, state="submitted", detail=f"{len(specs)} case runs"))
    runs = []
    for spec in specs:
        dumped = spec.model_dump(mode="json", exclude_computed_fields=True)
        runs.append(CaseRun(submission_id=submission.id, name=spec.name, kind=spec.kind, backend=spec.backend,
                            precision=spec.precision, spec=dumped, spec_key=spec_key(dumped)))
    session.add_all(runs)
    session.flush()  # one INSERT for every run (their ids for the events), not one round trip per run
    session.add_all([Event(submission_id=submission.id, case_run_id=run.id, state=CaseRunState.QUEUED,
                           detail=f"queue {run.backend}") for run in runs])
    return submission
