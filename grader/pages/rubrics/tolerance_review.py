"""A rubric version's review page (each tolerance beside the course's measured spread, flagged where a backend or
precision spread exceeds it; its sign-offs), the sign-off form, and drafting a new version from its tolerances.

Staff of the course read the review; only an instructor signs off or drafts (POST forms behind the pages' origin
check). A published draft goes on to the existing regrade preview, where the instructor commits it. A refused form
is shown again with each error beside its field; anything the caller may not see is the not-found page.
"""

from __future__ import annotations

from urllib.parse import quote

from fastapi import APIRouter, Request, status
from fastapi.responses import HTMLResponse, RedirectResponse

from grader.web.deps import SessionDep
from grader.pages.auth import InstructorCourse, SignedIn, StaffCourse
from grader.pages.templates import TEMPLATES
from grader.services.rubrics import tolerance_review as review
from grader.services.errors import Conflict, DomainError, Invalid

router = APIRouter(include_in_schema=False)


def _base(course: str, lesson: str, version: str) -> str:
    return f"/courses/{quote(course)}/rubrics/{quote(lesson)}/{quote(version)}"


def _review_page(request: Request, session, row, user, lesson: str, version: str, *, error: DomainError | None = None,
                 note: str = "", code: int = 200) -> HTMLResponse:
    data = review.version_review(session, course=row, lesson=lesson, version=version)
    return TEMPLATES.TemplateResponse(request, "rubrics/tolerance_review.html", {
        "user": user, "r": data, "base": _base(row.name, lesson, version), "error": error, "note": note},
        status_code=code)


@router.get("/courses/{course}/rubrics/{lesson}/{version}", response_class=HTMLResponse)
def rubric_review_page(request: Request, row: StaffCourse, session: SessionDep, user: SignedIn, lesson: str,
                       version: str):
    return _review_page(request, session, row, user, lesson, version)


@router.post("/courses/{course}/rubrics/{lesson}/{version}/signoff")
async def rubric_signoff(request: Request, row: InstructorCourse, session: SessionDep, user: SignedIn, lesson: str,
                         version: str):
    form = await request.form()
    note = str(form.get("note", ""))
    try:
        signoff = review.sign_off(session, course=row, user=user, lesson=lesson, version=version, note=note)
    except (Invalid, Conflict) as exc:
        session.rollback()
        return _review_page(request, session, row, user, lesson, version, error=exc, note=note,
                            code=422 if isinstance(exc, Invalid) else 409)
    return RedirectResponse(f"{_base(row.name, lesson, version)}#signoff-{signoff.id}",
                            status_code=status.HTTP_303_SEE_OTHER)


def _draft_page(request: Request, user, course: str, draft: review.Draft, *, error: DomainError | None = None,
                code: int = 200) -> HTMLResponse:
    errors = {e["field"]: e["rule"] for e in (error.errors if error else [])}
    return TEMPLATES.TemplateResponse(request, "rubrics/tolerance_review_draft.html", {
        "user": user, "course": course, "d": draft, "error": error, "errors": errors,
        "action": f"{_base(course, draft.lesson, draft.base_version)}/draft"}, status_code=code)


@router.get("/courses/{course}/rubrics/{lesson}/{version}/draft", response_class=HTMLResponse)
def rubric_draft_page(request: Request, row: InstructorCourse, session: SessionDep, user: SignedIn, lesson: str,
                      version: str):
    return _draft_page(request, user, row.name, review.draft_from(session, course=row, lesson=lesson, version=version))


@router.post("/courses/{course}/rubrics/{lesson}/{version}/draft")
async def rubric_draft_publish(request: Request, row: InstructorCourse, session: SessionDep, user: SignedIn,
                               lesson: str, version: str):
    form = await request.form()
    values = {k.removeprefix("value."): str(v) for k, v in form.multi_items() if k.startswith("value.")}
    rationales = {k.removeprefix("rationale."): str(v) for k, v in form.multi_items() if k.startswith("rationale.")}
    new_version, notes = str(form.get("version", "")), str(form.get("notes", ""))
    try:
        published = review.publish_draft(session, course=row, user=user, lesson=lesson, base_version=version,
                                         version=new_version, notes=notes, values=values, rationales=rationales)
    except (Invalid, Conflict) as exc:
        session.rollback()
        draft = review.draft_from(session, course=row, lesson=lesson, version=version)
        typed = draft.model_copy(update={"version": new_version, "notes": notes, "tolerances": [
            t.model_copy(update={"value": values.get(t.name, t.value),
                                 "rationale": rationales.get(t.name, t.rationale)}) for t in draft.tolerances]})
        return _draft_page(request, user, row.name, typed, error=exc, code=422 if isinstance(exc, Invalid) else 409)
    return RedirectResponse(f"/courses/{quote(row.name)}/regrade?version={quote(published.version)}"
                            f"&lesson={quote(lesson)}", status_code=status.HTTP_303_SEE_OTHER)
