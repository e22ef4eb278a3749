"""The backend-discrepancy audit log: its filters, the entries a course's staff read, the CSV export, and asking
for an audit re-run of a stored case run on another backend, precision or execution mode."""

from __future__ import annotations

import re
from datetime import date, datetime, time
from typing import Annotated, Any, Literal

from pydantic import BaseModel, BeforeValidator, ConfigDict, Field
from sqlalchemy import select
from sqlalchemy.orm import Session

from grader.core.audit import create_audit_rerun
from grader.core.states import Backend, CaseRunPurpose, CaseRunState, ExecutionMode, Precision
from grader.core.models import AuditEntry, CaseRun, Submission, User
from grader.core.schemas import as_utc
from grader.services.identity import quotas
from grader.services.identity.access import MAX_ID, require_staff
from grader.services.errors import Conflict, NotFound
from grader.services.sending import Sender
from grader.core.settings import settings
from rubric.exports import csv_text

Classification = Literal["identical", "within_tolerance", "numeric_drift", "relation_changed", "provenance_violation",
                         "not_compared"]



class AuditRerunRequest(BaseModel):
    model_config = ConfigDict(extra="forbid")

    backend: Backend = Backend.CPU
    precision: Precision = Precision.F32
    mode: ExecutionMode | None = None


def _iso_date(value: Any) -> Any:
    """Only YYYY-MM-DD, as documented (format: date); pydantic alone would also read `0` as 1970-01-01."""
    if isinstance(value, str) and not re.fullmatch(r"[0-9]{4}-[0-9]{2}-[0-9]{2}", value):
        raise ValueError("must be a date written YYYY-MM-DD")
    return value


IsoDate = Annotated[date, BeforeValidator(_iso_date)]


class Filters(BaseModel):
    """Filters of the log (query parameters; unknown ones are refused)."""

    model_config = ConfigDict(extra="forbid")

    lesson: Annotated[str | None, Field(pattern=r"^L[0-9]{2}$")] = None
    case: Annotated[str | None, Field(max_length=64)] = None
    classification: Classification | None = None
    backends: Annotated[str | None, Field(pattern=r"^(cpu|rocm|cuda),(cpu|rocm|cuda)$",
                                          description="Two backends, e.g. cpu,cuda: entries comparing exactly these")] = None
    since: IsoDate | None = None
    until: IsoDate | None = None


def filtered_entries(session: Session, user: User, filters: Filters, limit: int = 500) -> list[AuditEntry]:
    """The caller's course's entries (staff), newest first, under the filters."""
    require_staff(user, action="read the audit log")
    query = select(AuditEntry).where(AuditEntry.course_id == user.course_id)
    if filters.lesson:
        query = query.where(AuditEntry.lesson == filters.lesson)
    if filters.case:
        query = query.where(AuditEntry.case == filters.case)
    if filters.classification:
        query = query.where(AuditEntry.classification == filters.classification)
    if filters.since:
        query = query.where(AuditEntry.created_at >= datetime.combine(filters.since, time.min))
    if filters.until:
        query = query.where(AuditEntry.created_at <= datetime.combine(filters.until, time.max))
    rows = list(session.scalars(query.order_by(AuditEntry.id.desc()).limit(limit)))
    if filters.backends:
        wanted = sorted(b.strip() for b in filters.backends.split(",") if b.strip())
        rows = [e for e in rows if sorted(v.split("/")[0] for v in (e.left_variant, e.right_variant)) == wanted]
    return rows


def entry_of(session: Session, user: User, entry_id: int) -> AuditEntry:
    """One entry of the caller's course (staff); NotFound otherwise."""
    require_staff(user, action="read the audit log")
    entry = session.get(AuditEntry, entry_id) if 0 < entry_id <= MAX_ID else None
    if entry is None or entry.course_id != user.course_id:
        raise NotFound(f"audit entry {entry_id} not found")
    return entry


def recent_audit_runs(session: Session, user: User, limit: int = 20) -> list[CaseRun]:
    """The course's latest audit re-runs, newest first."""
    runs = session.scalars(select(CaseRun).join(Submission, CaseRun.submission_id == Submission.id)
                           .where(CaseRun.purpose == CaseRunPurpose.AUDIT, Submission.course_id == user.course_id)
                           .order_by(CaseRun.id.desc()).limit(limit))
    return list(runs)


def entries_csv(entries: list[AuditEntry]) -> str:
    rows: list[list] = [["entry_id", "created_at_utc", "lesson", "case", "left_case_run_id", "right_case_run_id",
                         "left_variant", "right_variant", "left_genesis", "right_genesis", "classification", "summary"]]
    for e in entries:
        versions = [((p or {}).get("versions") or {}).get("genesis", "") for p in (e.left_provenance, e.right_provenance)]
        rows.append([e.id, as_utc(e.created_at).isoformat(), e.lesson, e.case, e.left_case_run_id, e.right_case_run_id or "",
                     e.left_variant, e.right_variant, *versions, e.classification, e.summary])
    return csv_text(rows)


def request_rerun(*, session: Session, user: User, case_run_id: int, request: AuditRerunRequest,
                  sender: Sender) -> CaseRun:
    """Re-measure a stored case run on another backend, precision or execution mode (staff); the audit entry is
    written when it finishes. Conflict at once when there is nothing to compare or no worker listens on the queue."""
    require_staff(user, action="ask for audit re-runs")
    source = session.get(CaseRun, case_run_id) if 0 < case_run_id <= MAX_ID else None
    submission = session.get(Submission, source.submission_id) if source is not None else None
    if source is None or submission.course_id != user.course_id:
        raise NotFound(f"case run {case_run_id} not found")
    if source.status != CaseRunState.DONE or source.result_status != "ok":
        raise Conflict(f"case run {case_run_id} has no measurement to compare ({source.status}: {source.error})")
    if not sender.queue_listeners(request.backend):
        raise Conflict(f"no worker is listening on queue '{request.backend}': the re-run would wait forever; "
                       f"start a worker with `grader worker --queue {request.backend}` and ask again")
    pending = session.scalar(select(CaseRun).where(
        CaseRun.source_case_run_id == source.id, CaseRun.purpose == CaseRunPurpose.AUDIT,
        CaseRun.backend == request.backend, CaseRun.precision == request.precision,
        CaseRun.mode.is_(None) if request.mode is None else CaseRun.mode == request.mode,
        CaseRun.status.in_((CaseRunState.QUEUED, CaseRunState.RUNNING))).limit(1))
    if pending is not None:
        raise Conflict(f"audit re-run {pending.id} of case run {case_run_id} on {request.backend}/{request.precision}/"
                       f"{request.mode or 'default'} is already {pending.status}; its entry is written when it ends")
    quotas.take("audit re-runs", user.id, settings.rate_limit_audit_reruns, field="case_run_id")
    run = create_audit_rerun(session, source=source, backend=request.backend, precision=request.precision,
                             mode=request.mode, user=user)
    session.commit()
    sender.send_case_run(run.id, run.delivery, run.backend)
    return run
