"""Process one delivery of a case run: claim it, reuse a stored measurement or run the case, store the result.

The worker-side orchestration behind the `run_case_run` task. The state changes it makes are grader.core.lifecycle's;
the case runs through `run_case`, a parameter (spec, out_dir -> CaseResult), so this is testable without Genesis.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from sqlalchemy import and_, or_, select
from sqlalchemy.orm import Session

from rubric import parse_case

from grader.core import lifecycle
from grader.core.models import CaseRun, Measurement, utcnow
from grader.core.settings import settings
from grader.core import content_key
from grader.core.states import CaseRunPurpose, CaseRunState

# A run whose case an earlier run is measuring right now waits for that measurement, polling this often, at most
# this long (then it measures itself, as it always did). Bounded well inside the run's lease margin and the task's
# soft time limit (case_time_limit_s + 60), which must still hold a whole case after the wait.
IN_FLIGHT_POLL_S = 0.1
IN_FLIGHT_WAIT_MAX_S = 30.0


def reusable(*, session: Session, run: CaseRun, key_inputs: dict[str, Any]) -> Measurement | None:
    """Set the run's content key; the stored measurement under it, unless the submission forces a re-run."""
    run.content_key = content_key.content_key(key_inputs)
    if run.submission.force_rerun or run.purpose == "audit":  # an audit re-run exists to measure again
        return None
    return session.scalar(select(Measurement).where(Measurement.content_key == run.content_key))


def measuring_first(*, session: Session, run: CaseRun) -> CaseRun | None:
    """The grading run measuring the same content key right now (running under a live lease, not reusing), claimed
    before this one; None when there is none. Only an earlier claim counts (ties by id), so two runs never wait for
    each other: the first measures, the later ones wait for its measurement. A run held by a dead process of this
    host (a worker killed mid-case, its lease not yet over) measures nothing: nobody waits for it."""
    earlier = session.scalars(
        select(CaseRun).where(
            CaseRun.content_key == run.content_key, CaseRun.id != run.id, CaseRun.status == CaseRunState.RUNNING,
            CaseRun.purpose == CaseRunPurpose.GRADING, CaseRun.reused_from_id.is_(None),
            CaseRun.lease_until > utcnow(),
            or_(CaseRun.started_at < run.started_at, and_(CaseRun.started_at == run.started_at, CaseRun.id < run.id)))
        .order_by(CaseRun.started_at, CaseRun.id)).all()
    return next((other for other in earlier if not lifecycle.held_by_the_dead(other)), None)


def await_measurement(*, session: Session, run: CaseRun, limit_s: float = IN_FLIGHT_WAIT_MAX_S) -> Measurement | None:
    """While an earlier run measures this run's case (`measuring_first`), wait for its measurement instead of
    measuring the same case again beside it: on a busy host two slots stepping one case cost twice the CPU for one
    result (a class at the deadline queues the same baseline for every sheet). Returns the measurement to reuse, or
    None (measure): nothing in flight, it ended without one (failed, requeued), or `limit_s` passed. Holds no
    transaction while it waits (the caller committed the run's content key)."""
    if run.submission.force_rerun or run.purpose == CaseRunPurpose.AUDIT:
        return None
    deadline = time.monotonic() + min(limit_s, settings.lease_margin_s / 2)
    while measuring_first(session=session, run=run) is not None:
        session.rollback()  # no transaction held while waiting; nothing of this run is pending
        if time.monotonic() > deadline:
            return None
        time.sleep(IN_FLIGHT_POLL_S)
    return session.scalar(select(Measurement).where(Measurement.content_key == run.content_key))


def process_case_run(*, session: Session, case_run_id: int, delivery: int, run_case: Callable) -> int | None:
    """Claim, reuse or run, store, finish. Returns the submission id when this call moved it to grading."""
    run, started_grading = lifecycle.claim(session=session, case_run_id=case_run_id, delivery=delivery)
    session.commit()
    if run is None:
        return _submission_of(session, case_run_id) if started_grading else None
    key_inputs = content_key.key_inputs(run.spec, backend=run.backend, precision=run.precision)
    measurement = reusable(session=session, run=run, key_inputs=key_inputs)
    if measurement is not None:
        return run.submission_id if lifecycle.store_reused(session=session, run=run, measurement=measurement) else None
    session.commit()
    if (measurement := await_measurement(session=session, run=run)) is not None:
        return run.submission_id if lifecycle.store_reused(session=session, run=run, measurement=measurement) else None
    # The case process's folder: store_result copies its evidence into the database, after which it is a cache.
    out_dir = Path(settings.artifacts_dir) / "case-runs" / str(run.id) / f"try-{run.tries}"
    result = run_case(parse_case(run.spec), out_dir, **({"mode": run.mode} if run.mode else {}))
    stored = lifecycle.store_result(session=session, run=run, result=result, key_inputs=key_inputs)
    return run.submission_id if stored else None


def _submission_of(session: Session, case_run_id: int) -> int:
    return session.get(CaseRun, case_run_id).submission_id
