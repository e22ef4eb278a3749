"""The instructor's rubric pages: the course's rubric versions and regrades, a regrade's preview, and its commit.

Instructors and auditors of the course read them; only an instructor commits (a POST form; the session cookie is
SameSite=Strict, so another site cannot post it). Everything else is the 404 page, revealing nothing.
"""

from __future__ import annotations

from fastapi import APIRouter, Form, Request, status
from fastapi.responses import HTMLResponse, RedirectResponse

from grader.api.deps import SessionDep
from grader.core import rubrics as store
from grader.pages.auth import InstructorCourse, SignedIn, StaffCourse
from grader.pages.errors import not_found as _not_found
from grader.pages.templates import TEMPLATES
from grader.services.regrade import commit_regrade, preview_regrade, regrade_records, rubric_versions
from rubric import ArchivedRubric

router = APIRouter(include_in_schema=False)


@router.get("/courses/{course}/rubrics", response_class=HTMLResponse)
def rubrics_page(request: Request, row: StaffCourse, session: SessionDep, user: SignedIn, lesson: str = "L03"):
    if lesson not in ("L03",):
        return _not_found(request, user, f"rubrics of course {row.name} for lesson {lesson}")
    versions = rubric_versions(session, lesson)
    regrades = regrade_records(session, course=row, lesson=lesson)
    return TEMPLATES.TemplateResponse(request, "rubrics.html", {
        "user": user, "course": row.name, "lesson": lesson, "versions": versions, "regrades": regrades,
        "current": store.course_version(session, row.id, lesson)})


@router.get("/courses/{course}/regrade", response_class=HTMLResponse)
def regrade_preview_page(request: Request, row: StaffCourse, session: SessionDep, user: SignedIn, version: str = "",
                         lesson: str = "L03"):
    try:
        preview = preview_regrade(session, course=row, lesson=lesson, version=version)
    except (LookupError, ArchivedRubric) as exc:
        return TEMPLATES.TemplateResponse(request, "regrade.html", {
            "user": user, "course": row.name, "error": str(exc), "preview": None}, status_code=409)
    return TEMPLATES.TemplateResponse(request, "regrade.html", {
        "user": user, "course": row.name, "error": None, "preview": preview})


@router.post("/courses/{course}/regrade")
def regrade_commit_page(row: InstructorCourse, session: SessionDep, user: SignedIn,
                        version: str = Form(...), lesson: str = Form("L03")):
    regrade, _ = commit_regrade(session, course=row, lesson=lesson, version=version, user=user)
    return RedirectResponse(f"/courses/{row.name}/rubrics#regrade-{regrade.id}", status_code=status.HTTP_303_SEE_OTHER)
