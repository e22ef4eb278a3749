"""The instructor's rubric pages: the course's rubric versions and regrades, a regrade's preview, and its commit.

Instructors and auditors of the course read them; only an instructor commits (a POST form naming the content hash
it previewed; the session cookie is SameSite=Strict, so another site cannot post it). Everything else is the 404 page,
revealing nothing; another course's published versions are unknown here. A preview or commit refused (an unknown,
archived or changed version, a malformed field) is the regrade page with the reason, never a server error.
"""

from __future__ import annotations

from fastapi import APIRouter, Form, Request, status
from fastapi.responses import HTMLResponse, RedirectResponse

from grader.web.deps import SessionDep
from grader.core import rubrics as store
from grader.pages.auth import InstructorCourse, SignedIn, StaffCourse
from grader.pages.errors import not_found
from grader.pages.templates import TEMPLATES
from grader.services.errors import Conflict, DomainError, Invalid, NotFound
from grader.services.rubrics.regrade import commit_regrade, preview_regrade, regrade_records, rubric_versions
from grader.services.rubrics.tolerance_review import review_record, signoff_states
from rubric.governance import rubric_changes

router = APIRouter(include_in_schema=False)


@router.get("/courses/{course}/rubrics", response_class=HTMLResponse)
def rubrics_page(request: Request, row: StaffCourse, session: SessionDep, user: SignedIn, lesson: str = "L03"):
    if lesson not in ("L03",):
        return not_found(request, user, f"rubrics of course {row.name} for lesson {lesson}")
    versions = rubric_versions(session, course=row, lesson=lesson)
    regrades = regrade_records(session, course=row, lesson=lesson)
    signed = signoff_states(session, course=row, rows=versions)
    return TEMPLATES.TemplateResponse(request, "rubrics/rubrics.html", {
        "user": user, "course": row.name, "lesson": lesson, "versions": versions, "regrades": regrades,
        "current": store.course_version(session, row.id, lesson),
        "signoffs": signed, "reviewers": {v.version: review_record(v.content["review"]["reviewer"],
                                                                  signed_off=bool(signed[v.version]))
                                          for v in versions}})


def _refused(request: Request, user, course: str, exc: DomainError) -> HTMLResponse:
    code = next(c for kind, c in ((NotFound, 404), (Conflict, 409), (Invalid, 422), (DomainError, 400))
                if isinstance(exc, kind))
    return TEMPLATES.TemplateResponse(request, "rubrics/regrade.html", {
        "user": user, "course": course, "error": exc.detail, "errors": exc.errors, "preview": None},
        status_code=code)


@router.get("/courses/{course}/regrade", response_class=HTMLResponse)
def regrade_preview_page(request: Request, row: StaffCourse, session: SessionDep, user: SignedIn, version: str = "",
                         lesson: str = "L03"):
    try:
        preview = preview_regrade(session, course=row, lesson=lesson, version=version)
    except DomainError as exc:
        return _refused(request, user, row.name, exc)
    return TEMPLATES.TemplateResponse(request, "rubrics/regrade.html", {
        "user": user, "course": row.name, "error": None, "preview": preview,
        "from_current": _changes_from_current(session, row, preview)})


def _changes_from_current(session, row, preview) -> list[str]:
    """What the new version changes against the course's current one, for a preview with no graded submission to
    compare (its per-version changes are then empty, and the instructor still needs to see what they commit)."""
    if preview.rubric_changes or preview.current_version == preview.new_version:
        return []
    current = store.get_version(session, preview.lesson, preview.current_version, course_id=row.id)
    new = store.get_version(session, preview.lesson, preview.new_version, course_id=row.id)
    session.rollback()  # recording shipped versions is the only write reading them may cause; a preview keeps none
    return rubric_changes(current, new)


@router.post("/courses/{course}/regrade")
def regrade_commit_page(request: Request, row: InstructorCourse, session: SessionDep, user: SignedIn,
                        version: str = Form(""), lesson: str = Form("L03"), content_hash: str = Form("")):
    try:
        regrade, _ = commit_regrade(session, course=row, lesson=lesson, version=version, content_hash=content_hash,
                                    user=user)
    except DomainError as exc:
        return _refused(request, user, row.name, exc)
    return RedirectResponse(f"/courses/{row.name}/rubrics#regrade-{regrade.id}", status_code=status.HTTP_303_SEE_OTHER)
