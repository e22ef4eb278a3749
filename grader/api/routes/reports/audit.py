"""The backend-discrepancy audit log for auditors and instructors: entries with filters, one entry, CSV and JSON
export, and audit re-runs of a stored case run on another backend, precision or execution mode."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Query, status
from fastapi.responses import PlainTextResponse, Response

from grader.api.schemas import AuditEntryPublic
from grader import dispatch
from grader.web.deps import RowId, SessionDep, StaffUser
from grader.api.responses import csv_ok, errors
from grader.core.schemas import CaseRunPublic
from grader.services.reports import audit
from grader.services.reports.audit import AuditRerunRequest, Filters

router = APIRouter(tags=["audit"], responses=errors(401, 403, 422))


FilterDep = Annotated[Filters, Query()]


@router.get("/audit/entries", response_model=list[AuditEntryPublic])
def list_entries(session: SessionDep, user: StaffUser, filters: FilterDep):
    """The course's audit entries, newest first (at most 500), filtered by lesson, case, class, backend pair, date."""
    return audit.filtered_entries(session, user, filters)


@router.get("/audit/entries.csv", response_class=Response, responses=csv_ok("One row per entry"))
def export_entries(session: SessionDep, user: StaffUser, filters: FilterDep):
    """The filtered log as CSV: one row per entry with both runs, variants, class and summary."""
    return PlainTextResponse(audit.entries_csv(audit.filtered_entries(session, user, filters)),
                             media_type="text/csv")


@router.get("/audit/entries/{entry_id}", response_model=AuditEntryPublic, responses=errors(404))
def get_entry(entry_id: RowId, session: SessionDep, user: StaffUser):
    """One entry: both runs' provenance, every array and metric difference, the relations and the class."""
    return audit.entry_of(session, user, entry_id)


@router.post("/case-runs/{case_run_id}/audit-reruns", response_model=CaseRunPublic,
             status_code=status.HTTP_202_ACCEPTED,
             responses=errors(404, 409, 413, 429, _409="Nothing to compare, or no worker listens",
                              _429="More audit re-runs than RATE_LIMIT_AUDIT_RERUNS allows (Retry-After says when)"))
def request_rerun(case_run_id: RowId, request: AuditRerunRequest, session: SessionDep, user: StaffUser):
    """Re-measure a stored case run on another backend, precision or execution mode; the audit entry is written
    when it finishes. Refused at once (409) when no worker listens on the backend's queue."""
    return audit.request_rerun(session=session, user=user, case_run_id=case_run_id, request=request,
                               sender=dispatch)
