"""The instructor's LTI page (/courses/C/lti): the course's platform registrations and LMS courses, each
assignment's line item with the last score sent to every student, the sends still due or failing (the error and the
next retry), and a "retry now" button. Sending itself is grader.services.lti.outbox's."""

from __future__ import annotations

from fastapi import APIRouter, Request, status
from fastapi.responses import HTMLResponse, RedirectResponse

from grader.web.deps import SessionDep
from grader.core.timezones import iso
from grader.pages.auth import InstructorCourse, SignedIn
from grader.pages.templates import TEMPLATES
from grader.services.lti import outbox as lti_outbox

router = APIRouter(include_in_schema=False)


def _report_url(request: Request) -> str:
    return str(request.base_url).rstrip("/") + "/submissions/{id}"


@router.get("/courses/{course}/lti", response_class=HTMLResponse)
def lti_page(request: Request, row: InstructorCourse, session: SessionDep, user: SignedIn, retried: int = -1):
    overview = lti_outbox.course_overview(session=session, course=row)
    return TEMPLATES.TemplateResponse(request, "lti/outbox.html", {
        "user": user, "course": row.name, "overview": overview, "retried": retried,
        "at": lambda when: iso(when, row.timezone) if when else ""})


@router.post("/courses/{course}/lti/retry")
def retry_page(request: Request, row: InstructorCourse, session: SessionDep, user: SignedIn):
    """Sends every failed or pending score of the course now, whatever its backoff; the page shows the outcome."""
    passes = lti_outbox.retry_now(session=session, course=row, report_url=_report_url(request))
    return RedirectResponse(f"/courses/{row.name}/lti?retried={len(passes)}#sends",
                            status_code=status.HTTP_303_SEE_OTHER)
