"""The audit log's shared vocabulary: which runs measure the same case (spec_key), how a measurement's variant is
named, and creating an audit re-run of a stored case run. Used by the API (requests, pages) and the worker (entries).
"""

from __future__ import annotations

import hashlib
import json
from typing import Any

from sqlalchemy import func, select
from sqlalchemy.orm import Session

from grader.core.states import CaseRunState
from grader.core.models import CaseRun, Event, User

# The case process's wording for a run that did not run on what it asked for (worker.case_process).
PROVENANCE_MARKERS = ("provenance error", "provenance.actual_backend", "provenance.requested_backend",
                      "provenance.torch_hip", "provenance violation")
# Fields that say where and how a case runs, not what it is: runs differing only in these measure one case.
NOT_PHYSICS = ("name", "backend", "precision")


def spec_key(spec: dict[str, Any]) -> str:
    physics = {k: v for k, v in spec.items() if k not in NOT_PHYSICS}
    return hashlib.sha256(json.dumps(physics, sort_keys=True, separators=(",", ":")).encode()).hexdigest()


def variant(run: CaseRun) -> str:
    """"backend/precision/mode" as measured (actual backend and execution mode from provenance where known)."""
    provenance = run.provenance or {}
    mode = provenance.get("execution_mode") or run.mode or "default"
    return f"{run.actual_backend or run.backend}/{run.precision}/{mode}"


def create_audit_rerun(session: Session, *, source: CaseRun, backend: str, precision: str, mode: str | None,
                       user: User) -> CaseRun:
    """A new case run re-measuring `source` on another backend, precision or mode (flushes; the caller sends it).

    It belongs to the source's submission for its evidence and access rules, but its purpose is "audit": it never
    moves the submission's state, never counts in a grade, and never reuses a stored measurement.
    """
    n = session.scalar(select(func.count()).select_from(CaseRun).where(CaseRun.submission_id == source.submission_id,
                                                                       CaseRun.purpose == "audit")) + 1
    spec = dict(source.spec, backend=backend, precision=precision)
    run = CaseRun(submission_id=source.submission_id, name=f"audit-{n}:{source.name}"[:64], kind=source.kind,
                  backend=backend, precision=precision, spec=spec, purpose="audit", mode=mode,
                  source_case_run_id=source.id, requested_by_id=user.id, spec_key=spec_key(source.spec))
    session.add(run)
    session.flush()
    session.add(Event(submission_id=source.submission_id, case_run_id=run.id, state=CaseRunState.QUEUED,
                      detail=f"audit re-run of case run {source.id} ({variant(source)}) on "
                             f"{backend}/{precision}/{mode or 'default'}, requested by {user.name}"))
    return run
