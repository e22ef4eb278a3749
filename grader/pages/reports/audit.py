"""The audit pages (auditors and instructors of the course): the log with filters, one entry with both runs'
figures and provenance side by side, the entry's figures, the CSV, and the form asking for an audit re-run."""

from __future__ import annotations

from pathlib import Path
from urllib.parse import urlencode

from fastapi import APIRouter, Form, Request, status
from fastapi.responses import FileResponse, HTMLResponse, PlainTextResponse, RedirectResponse
from pydantic import ValidationError

from grader import dispatch
from grader.web.deps import MAX_ID, SessionDep
from grader.i18n import N_
from grader.core.models import AuditEntry
from grader.pages.auth import SignedIn, Staff
from grader.pages.errors import not_found
from grader.pages.templates import TEMPLATES
from grader.services.reports import audit
from grader.services.reports.audit import AuditRerunRequest, Filters, entries_csv, filtered_entries
from grader.services.errors import DomainError, Forbidden, NotFound

router = APIRouter(include_in_schema=False)
# The labels are msgids (N_): the pages show them in the reader's language through the `msg` filter.
CLASS_TEXT = {
    "identical": N_("identical"), "within_tolerance": N_("within the reviewed tolerance"),
    "numeric_drift": N_("numeric drift"), "relation_changed": N_("a qualitative relation changed"),
    "provenance_violation": N_("provenance violation"), "not_compared": N_("not compared"),
}


def _filters(request: Request) -> tuple[Filters, str | None]:
    raw = {k: v for k, v in request.query_params.items() if v}
    try:
        return Filters.model_validate(raw), None
    except ValidationError as exc:
        return Filters(), "; ".join(f"{'.'.join(map(str, e['loc']))}: {e['msg']}" for e in exc.errors())


@router.get("/audit", response_class=HTMLResponse)
def audit_page(request: Request, session: SessionDep, user: Staff):
    filters, error = _filters(request)
    entries = filtered_entries(session, user, filters)
    runs = audit.recent_audit_runs(session, user)
    return TEMPLATES.TemplateResponse(request, "reports/audit.html", {
        "user": user, "entries": entries, "filters": filters, "error": error, "classes": CLASS_TEXT,
        "audit_runs": runs, "query": request.url.query, "message": request.query_params.get("message")},
        status_code=422 if error else 200)


@router.get("/audit.csv")
def audit_csv(request: Request, session: SessionDep, user: Staff):
    filters, error = _filters(request)
    if error:
        return PlainTextResponse(error, status_code=422)
    return PlainTextResponse(entries_csv(filtered_entries(session, user, filters)), media_type="text/csv",
                             headers={"Content-Disposition": 'attachment; filename="audit-log.csv"'})


def _entry(session, user, entry_id: int) -> AuditEntry | None:
    try:
        return audit.entry_of(session, user, entry_id)
    except (NotFound, Forbidden):
        return None


@router.get("/audit/{entry_id}", response_class=HTMLResponse)
def audit_entry_page(request: Request, entry_id: int, session: SessionDep, user: SignedIn):
    entry = _entry(session, user, entry_id)
    if entry is None:
        return not_found(request, user, f"audit entry {entry_id}")
    keys = sorted(set(entry.left_provenance or {}) | set(entry.right_provenance or {}))
    return TEMPLATES.TemplateResponse(request, "reports/audit_entry.html", {
        "user": user, "e": entry, "c": entry.comparison or {}, "classes": CLASS_TEXT, "provenance_keys": keys})


@router.get("/audit/{entry_id}/figures/{filename}")
def audit_figure(request: Request, entry_id: int, filename: str, session: SessionDep, user: SignedIn):
    entry = _entry(session, user, entry_id)
    if entry is None or filename not in entry.figures or not entry.figures_dir:
        return not_found(request, user, f"figure {filename}")
    path = Path(entry.figures_dir) / filename
    if not path.is_file():
        return not_found(request, user, f"figure {filename}")
    return FileResponse(path, media_type="image/png")


@router.post("/audit/reruns")
def audit_rerun_form(request: Request, session: SessionDep, user: Staff,
                     case_run_id: int = Form(..., ge=1, le=MAX_ID),  # request_rerun trusts the API's bound
                     backend: str = Form("cpu"), precision: str = Form("32"), mode: str = Form("")):
    try:
        wanted = AuditRerunRequest(backend=backend, precision=precision, mode=mode or None)
        run = audit.request_rerun(session=session, user=user, case_run_id=case_run_id, request=wanted,
                                  sender=dispatch)
        message = f"Audit re-run {run.name} (case run {run.id}) queued on {run.backend}; its entry appears here when it finishes."
    except DomainError as exc:  # shown on the log's page beside the form, as the form's answer
        session.rollback()
        message = f"Refused: {exc.detail}"
    except ValidationError as exc:
        message = "Refused: " + "; ".join(f"{'.'.join(map(str, e['loc']))}: {e['msg']}" for e in exc.errors())

    return RedirectResponse(f"/audit?{urlencode({'message': message})}", status_code=status.HTTP_303_SEE_OTHER)
