"""Process one delivery of a case run: claim it, reuse a stored measurement or run the case, store the result.

The worker-side orchestration behind the `run_case_run` task. The state changes it makes are grader.core.lifecycle's;
the case runs through `run_case`, a parameter (spec, out_dir -> CaseResult), so this is testable without Genesis.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

from sqlalchemy import select
from sqlalchemy.orm import Session

from rubric import parse_case

from grader.core import lifecycle
from grader.core.models import CaseRun, Measurement
from grader.core.settings import settings
from grader.core import content_key


def reusable(*, session: Session, run: CaseRun, key_inputs: dict[str, Any]) -> Measurement | None:
    """Set the run's content key; the stored measurement under it, unless the submission forces a re-run."""
    run.content_key = content_key.content_key(key_inputs)
    if run.submission.force_rerun or run.purpose == "audit":  # an audit re-run exists to measure again
        return None
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
    # The case process's folder: store_result copies its evidence into the database, after which it is a cache.
    out_dir = Path(settings.artifacts_dir) / "case-runs" / str(run.id) / f"try-{run.tries}"
    result = run_case(parse_case(run.spec), out_dir, **({"mode": run.mode} if run.mode else {}))
    stored = lifecycle.store_result(session=session, run=run, result=result, key_inputs=key_inputs)
    return run.submission_id if stored else None


def _submission_of(session: Session, case_run_id: int) -> int:
    return session.get(CaseRun, case_run_id).submission_id
