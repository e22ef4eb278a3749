"""The backend-discrepancy audit log for auditors and instructors: entries with filters, one entry, CSV and JSON
export, and audit re-runs of a stored case run on another backend, precision or execution mode."""

from __future__ import annotations

import csv
import io
import re
from datetime import date, datetime, time
from typing import Annotated, Any, Literal

from fastapi import APIRouter, HTTPException, Query, status
from fastapi.responses import PlainTextResponse, Response
from pydantic import BaseModel, BeforeValidator, ConfigDict, Field
from sqlalchemy import select
from sqlalchemy.orm import Session

from grader import dispatch
from grader.api.deps import CurrentUser, RowId, SessionDep
from grader.api.responses import csv_ok, errors
from grader.core.audit import create_audit_rerun
from grader.models import AuditEntry, CaseRun, Submission, User
from grader.schemas import CaseRunPublic, UtcDateTime, as_utc

router = APIRouter(tags=["audit"], responses=errors(401, 403, 422))
Classification = Literal["identical", "within_tolerance", "numeric_drift", "relation_changed", "provenance_violation",
                         "not_compared"]


class AuditEntryPublic(BaseModel):
    model_config = ConfigDict(from_attributes=True)

    id: int
    created_at: UtcDateTime
    lesson: str
    case: str
    spec_key: str
    spec: dict[str, Any]
    left_case_run_id: int
    right_case_run_id: int | None
    left_variant: str
    right_variant: str
    left_provenance: dict[str, Any] | None
    right_provenance: dict[str, Any] | None
    classification: str
    summary: str
    comparison: dict[str, Any] | None
    figures: list[str]
    requested_by_id: int | None


class AuditRerunRequest(BaseModel):
    model_config = ConfigDict(extra="forbid")

    backend: Literal["cpu", "rocm", "cuda"] = "cpu"
    precision: Literal["32", "64"] = "32"
    mode: Literal["isolated", "warm"] | None = None


def staff(user: User) -> None:
    if user.role == "student":
        raise HTTPException(status.HTTP_403_FORBIDDEN, "the audit log is for auditors and instructors")


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
    """The caller's course's entries, newest first, under the filters."""
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
    entry = session.get(AuditEntry, entry_id)
    if entry is None or entry.course_id != user.course_id:
        raise HTTPException(status.HTTP_404_NOT_FOUND, f"audit entry {entry_id} not found")
    return entry


FilterDep = Annotated[Filters, Query()]


@router.get("/audit/entries", response_model=list[AuditEntryPublic])
def list_entries(session: SessionDep, user: CurrentUser, filters: FilterDep):
    """The course's audit entries, newest first (at most 500), filtered by lesson, case, class, backend pair, date."""
    staff(user)
    return filtered_entries(session, user, filters)


@router.get("/audit/entries.csv", response_class=Response, responses=csv_ok("One row per entry"))
def export_entries(session: SessionDep, user: CurrentUser, filters: FilterDep):
    """The filtered log as CSV: one row per entry with both runs, variants, class and summary."""
    staff(user)
    return PlainTextResponse(entries_csv(filtered_entries(session, user, filters)), media_type="text/csv")


def entries_csv(entries: list[AuditEntry]) -> str:
    out = io.StringIO()
    writer = csv.writer(out)
    writer.writerow(["entry_id", "created_at_utc", "lesson", "case", "left_case_run_id", "right_case_run_id",
                     "left_variant", "right_variant", "left_genesis", "right_genesis", "classification", "summary"])
    for e in entries:
        versions = [((p or {}).get("versions") or {}).get("genesis", "") for p in (e.left_provenance, e.right_provenance)]
        writer.writerow([e.id, as_utc(e.created_at).isoformat(), e.lesson, e.case, e.left_case_run_id, e.right_case_run_id or "",
                         e.left_variant, e.right_variant, *versions, e.classification, e.summary])
    return out.getvalue()


@router.get("/audit/entries/{entry_id}", response_model=AuditEntryPublic, responses=errors(404))
def get_entry(entry_id: RowId, session: SessionDep, user: CurrentUser):
    """One entry: both runs' provenance, every array and metric difference, the relations and the class."""
    staff(user)
    return entry_of(session, user, entry_id)


@router.post("/case-runs/{case_run_id}/audit-reruns", response_model=CaseRunPublic,
             status_code=status.HTTP_202_ACCEPTED,
             responses=errors(404, 409, 413, _409="Nothing to compare, or no worker listens"))
def request_rerun(case_run_id: RowId, request: AuditRerunRequest, session: SessionDep, user: CurrentUser):
    """Re-measure a stored case run on another backend, precision or execution mode; the audit entry is written
    when it finishes. Refused at once (409) when no worker listens on the backend's queue."""
    staff(user)
    source = session.get(CaseRun, case_run_id)
    submission = session.get(Submission, source.submission_id) if source is not None else None
    if source is None or submission.course_id != user.course_id:
        raise HTTPException(status.HTTP_404_NOT_FOUND, f"case run {case_run_id} not found")
    if source.status != "done" or source.result_status != "ok":
        raise HTTPException(status.HTTP_409_CONFLICT,
                            f"case run {case_run_id} has no measurement to compare ({source.status}: {source.error})")
    listeners = dispatch.queue_listeners(request.backend)
    if not listeners:
        raise HTTPException(status.HTTP_409_CONFLICT,
                            f"no worker is listening on queue '{request.backend}': the re-run would wait forever; "
                            f"start a worker with `grader worker --queue {request.backend}` and ask again")
    run = create_audit_rerun(session, source=source, backend=request.backend, precision=request.precision,
                             mode=request.mode, user=user)
    session.commit()
    dispatch.send_case_run(run.id, run.attempt, run.backend)
    return run
