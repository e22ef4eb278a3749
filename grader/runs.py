"""Case-run lifecycle in the database: claim a delivery, reuse or store a measurement, finish, start grading once.

Plain functions called by the thin Celery tasks in worker.tasks; the runner is a parameter (a callable
spec, out_dir -> CaseResult), so the lifecycle is testable without Genesis and never imports it.
"""

from __future__ import annotations

import os
import socket
from collections.abc import Callable
from datetime import timedelta
from pathlib import Path

from sqlalchemy import func, select, update
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from grader import reuse
from grader.models import CaseRun, Event, Measurement, Submission, utcnow
from grader.settings import settings

TERMINAL = ("done", "failed")
HOST = socket.gethostname()


def _pid_alive(pid: int | None) -> bool:
    if not pid:
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def claim(*, session: Session, case_run_id: int, attempt: int) -> tuple[CaseRun | None, bool]:
    """(run, False) when the run is now ours; (None, started_grading) when this delivery must not run it.

    Stale deliveries (finished, superseded attempt, held by a live worker) are dropped.

    A redelivery of the same attempt may take over a running case run when the process that held it is dead
    (same host) or its lease has expired; every take-over counts in `tries`, which is bounded.
    """
    run = session.get(CaseRun, case_run_id, with_for_update=True)
    if run is None or run.attempt != attempt or run.status in TERMINAL:
        return None, False
    now = utcnow()
    if run.status == "running":
        ours = run.worker == HOST and (run.worker_pid == os.getpid() or not _pid_alive(run.worker_pid))
        if not ours and run.lease_until and run.lease_until > now:
            return None, False
    if run.tries >= settings.max_infra_retries + 1:
        error = f"gave up after {run.tries} deliveries lost to worker failures"
        return None, _finish(session, run, status="failed", error=error)
    run.status, run.tries = "running", run.tries + 1
    run.worker, run.worker_pid = HOST, os.getpid()
    run.started_at, run.lease_until = now, now + timedelta(seconds=settings.lease_s)
    session.add(Event(submission_id=run.submission_id, case_run_id=run.id, state="running",
                      detail=f"{HOST} pid {os.getpid()} try {run.tries}"))
    return run, False


def reusable(*, session: Session, run: CaseRun) -> Measurement | None:
    inputs = reuse.key_inputs(run.spec, backend=run.backend, precision=run.precision)
    run.content_key = reuse.content_key(inputs)
    if run.submission.force_rerun:
        return None
    return session.scalar(select(Measurement).where(Measurement.content_key == run.content_key))


def execute(*, session: Session, case_run_id: int, attempt: int, runner: Callable) -> int | None:
    """Claim, reuse or run, store, finish. Returns the submission id when this call moved it to grading."""
    run, started_grading = claim(session=session, case_run_id=case_run_id, attempt=attempt)
    session.commit()
    if run is None:
        return _submission_of(session, case_run_id) if started_grading else None
    measurement = reusable(session=session, run=run)
    if measurement is not None:
        run.measurement_id, run.reused_from_id = measurement.id, measurement.case_run_id
        run.provenance, run.artifact_dir = measurement.provenance, measurement.artifact_dir
        run.metrics = measurement.metrics
        run.actual_backend, run.result_status = measurement.backend, "ok"
        detail = f"reused measurement {measurement.id} of case run {measurement.case_run_id}"
        return run.submission_id if _finish(session, run, status="done", detail=detail) else None
    session.commit()
    from rubric import parse_case

    out_dir = Path(settings.artifacts_dir) / "case-runs" / str(run.id) / f"try-{run.tries}"
    result = runner(parse_case(run.spec), out_dir)
    return run.submission_id if store_result(session=session, run=run, result=result) else None


def _submission_of(session: Session, case_run_id: int) -> int:
    return session.get(CaseRun, case_run_id).submission_id


def store_result(*, session: Session, run: CaseRun, result) -> bool:
    """Record a CaseResult (ok or not) on the run; an ok one becomes a reusable Measurement."""
    provenance = result.provenance.model_dump(mode="json") if result.provenance else None
    run.result_status, run.error, run.wall_s = result.status, result.error, result.wall_s
    run.provenance, run.artifact_dir = provenance, result.out_dir
    run.metrics = result.metrics.model_dump(mode="json") if result.metrics is not None else None
    run.actual_backend = result.provenance.actual_backend if result.provenance else None
    run.stderr_tail = (result.stderr or "")[-4000:] or None
    if result.ok:
        _record_measurement(session, run, provenance)
    return _finish(session, run, status="done" if result.ok else "failed",
                   detail=f"{result.status} in {result.wall_s:.1f} s" + (f": {result.error}" if result.error else ""))


def _record_measurement(session: Session, run: CaseRun, provenance: dict) -> None:
    inputs = reuse.key_inputs(run.spec, backend=run.backend, precision=run.precision)
    try:
        with session.begin_nested():
            m = Measurement(content_key=reuse.content_key(inputs), key_inputs=inputs, case_run_id=run.id,
                            backend=run.actual_backend, provenance=provenance, metrics=run.metrics,
                            artifact_dir=run.artifact_dir)
            session.add(m)
        run.measurement_id = m.id
    except IntegrityError:
        pass  # the same key was measured concurrently (force_rerun); this run keeps its own evidence


def _finish(session: Session, run: CaseRun, *, status: str, error: str | None = None, detail: str | None = None) -> bool:
    # Lock the submission first: finishers of one submission serialize, so exactly one sees the last run done.
    session.execute(select(Submission.id).where(Submission.id == run.submission_id).with_for_update())
    submission = session.get(Submission, run.submission_id)
    run.status, run.finished_at, run.lease_until = status, utcnow(), None
    if error:
        run.error = error
    session.add(Event(submission_id=run.submission_id, case_run_id=run.id, state=status, detail=detail or error))
    session.flush()
    open_runs = session.scalar(select(func.count()).select_from(CaseRun).where(
        CaseRun.submission_id == submission.id, CaseRun.status.not_in(TERMINAL)))
    started = False
    if open_runs == 0:
        started = session.execute(
            update(Submission).where(Submission.id == submission.id, Submission.status == "running")
            .values(status="grading", grading_at=utcnow(), updated_at=utcnow())
        ).rowcount == 1
        if started:
            session.add(Event(submission_id=submission.id, state="grading"))
    session.commit()
    return started
