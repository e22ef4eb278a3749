"""The review pages: the course's queue of review requests with their answers (instructors answer, auditors read),
and the report page's two forms: a student's review request and an instructor's override of one item.

Every form here is a POST under the origin check (grader.pages.csrf, on the whole page router). A refusal the
person can mend (a missing comment, a score outside the item's points) names the field and the rule beside the form:
on the queue page, and on the report page for its override form (what was typed kept); the review request form's
refusals are the error page (grader.pages.errors).
"""

from __future__ import annotations

import math

from fastapi import APIRouter, Form, Request, status
from fastapi.responses import HTMLResponse, RedirectResponse

from grader.web.deps import SessionDep
from grader.web.errors import status_of
from grader.core.grades import current_grade
from grader.core.models import Course
from grader.pages.auth import InstructorCourse, SignedIn, StaffCourse
from grader.pages.submissions.report import report_response
from grader.pages.templates import TEMPLATES
from grader.pages.views import VERDICT_LABEL
from grader.services.identity import access
from grader.services.submissions import overrides, review_requests
from grader.services.errors import Conflict, Invalid

router = APIRouter(include_in_schema=False)


def _score(text: str, *, required: bool) -> float | None:
    """A form's score field as a number; Invalid naming it when it is not one (or is missing where required)."""
    text = text.strip()
    if not text:
        if required:
            raise Invalid("invalid override", [{"field": "score", "rule": "required: a number of points"}])
        return None
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not math.isfinite(value):
        raise Invalid("invalid score", [{"field": "score", "rule": f"must be a number of points, not {text[:40]!r}"}])
    return value


def _items_now(session, requests) -> dict[int, dict]:
    """Request id -> its item as the submission's current grade has it (score, points, measured verdict, and whether
    an instructor set the score): staff read every item, withheld or not, so the queue shows each beside its request."""
    grades: dict[int, dict] = {}
    out = {}
    for r in requests:
        if r.submission_id not in grades:
            grade = current_grade(session, r.submission_id)
            grades[r.submission_id] = {i["id"]: i for i in (grade.report if grade else {}).get("items", [])}
        item = grades[r.submission_id].get(r.item_id)
        if item is not None:
            out[r.id] = {"score": item.get("score"), "points": item.get("points"), "verdict": item.get("verdict"),
                         "verdict_label": VERDICT_LABEL.get(item.get("verdict"), item.get("verdict")),
                         "overridden": bool(item.get("override"))}
    return out


def _queue(request: Request, session, user, course: Course, *, answered: int | None = None, failed: int | None = None,
           error: Invalid | Conflict | None = None, status_code: int = 200) -> HTMLResponse:
    waiting = review_requests.course_requests(session=session, course_id=course.id, state="open")
    done = review_requests.course_requests(session=session, course_id=course.id, state="answered")
    return TEMPLATES.TemplateResponse(request, "submissions/review_requests.html", {
        "user": user, "course": course.name, "open": waiting, "answered": done, "now": _items_now(session, waiting + done),
        "just_answered": answered, "failed": failed, "error": error}, status_code=status_code)


@router.get("/courses/{course}/reviews", response_class=HTMLResponse)
def reviews_page(request: Request, row: StaffCourse, session: SessionDep, user: SignedIn, answered: int | None = None):
    return _queue(request, session, user, row, answered=answered)


@router.post("/courses/{course}/reviews/{request_id}/answer", response_class=HTMLResponse)
def answer_form(request: Request, row: InstructorCourse, request_id: int, session: SessionDep, user: SignedIn,
                answer: str = Form(""), score: str = Form("")):
    """An instructor's answer, with a new score for the item when one is typed."""
    asked = review_requests.request_of(session=session, user=user, request_id=request_id)
    try:
        review_requests.answer(session=session, request=asked, user=user, text=answer,
                               score=_score(score, required=False))
    except (Invalid, Conflict) as refused:  # shown beside the form it came from; nothing was stored
        session.rollback()
        return _queue(request, session, user, row, failed=request_id, error=refused, status_code=status_of(refused))
    return RedirectResponse(f"/courses/{row.name}/reviews?answered={request_id}#answered-{request_id}",
                            status_code=status.HTTP_303_SEE_OTHER)


@router.post("/submissions/{submission_id}/overrides")
def override_form(request: Request, submission_id: int, session: SessionDep, user: SignedIn, item_id: str = Form(""),
                  score: str = Form(""), comment: str = Form("")):
    """The report page's override form (instructors of the course; anyone else gets the not-found page). A refusal
    the instructor can mend is the report page again, the error beside the form and what was typed kept."""
    submission = access.readable_submission(session=session, user=user, submission_id=submission_id)
    try:
        overrides.set_override(session=session, submission=submission, user=user, item_id=item_id,
                               score=_score(score, required=True), comment=comment)
    except (Invalid, Conflict) as refused:  # nothing was stored
        session.rollback()
        return report_response(request, session, user, submission, status_code=status_of(refused), extra={
            "override_error": refused, "override_typed": {"item_id": item_id, "score": score, "comment": comment}})
    return RedirectResponse(f"/submissions/{submission_id}#override-{item_id}", status_code=status.HTTP_303_SEE_OTHER)


@router.post("/submissions/{submission_id}/review-requests")
def review_request_form(submission_id: int, session: SessionDep, user: SignedIn, item_id: str = Form(""),
                        message: str = Form("")):
    """The report page's review request form (the submission's student)."""
    submission = access.readable_submission(session=session, user=user, submission_id=submission_id)
    made = review_requests.ask(session=session, submission=submission, user=user, item_id=item_id, message=message)
    return RedirectResponse(f"/submissions/{submission_id}#review-{made.id}", status_code=status.HTTP_303_SEE_OTHER)
