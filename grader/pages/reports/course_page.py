"""A student's course page (`/courses/COURSE`): the course's assignments with the dates that apply to them, what a
submission now would meet, their attempts and the score that counts so far, and their own lab's parameters at an
assignment with a variant pool (grader.services.reports.course_page). The
course's staff are sent to its class dashboard; anyone else gets the not-found page."""

from __future__ import annotations

from fastapi import APIRouter, Request, status
from fastapi.responses import HTMLResponse, RedirectResponse

from grader.web.deps import SessionDep
from grader.pages.auth import SignedIn
from grader.pages.templates import TEMPLATES, request_locale
from grader.services.reports.course_page import student_course
from grader.services.errors import NotFound
from grader.services.identity import access

router = APIRouter(include_in_schema=False)


@router.get("/courses/{course}", response_class=HTMLResponse)
def course_page(request: Request, course: str, session: SessionDep, user: SignedIn):
    if user.course.name != course:
        raise NotFound(f"page of course {course}")
    if access.is_staff(user):
        return RedirectResponse(f"/courses/{course}/dashboard", status_code=status.HTTP_303_SEE_OTHER)
    return TEMPLATES.TemplateResponse(request, "reports/course_page.html", {
        "user": user, "lines": student_course(session=session, student=user, locale=request_locale(request))})
