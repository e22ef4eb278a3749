"""The instructor's page of one assignment: its settings (times in the course's zone), and per student the dates
that apply (their extension, with who granted it), every attempt with its lateness, raw score, late penalty and
counted score, and which attempt counts; and its forms: release the withheld items, grant or revoke a student's
extension (dates typed in the course's zone), each recorded in the course's changes, listed here for this
assignment. For the course's instructors; anyone else gets the 404 page."""

from __future__ import annotations

from fastapi import APIRouter, Form, Request, status
from fastapi.responses import HTMLResponse, PlainTextResponse, RedirectResponse

from grader.web.deps import SessionDep
from grader.core.models import Assignment
from grader.pages.auth import InstructorsAssignment, SignedIn
from grader.pages.setup.courses import checked_form
from grader.pages.templates import TEMPLATES
from grader.services.setup import assignments as logic
from grader.services.setup import course_changes
from grader.services.reports import exports
from grader.services.errors import Invalid
from grader.services.submissions.visibility import visibility_of

router = APIRouter(include_in_schema=False)


def _page(request: Request, session, user, assignment: Assignment, *, section: str | None = None,
          errors: list[dict[str, str]] | None = None, posted: dict[str, str] | None = None,
          status_code: int = status.HTTP_200_OK) -> HTMLResponse:
    """The page; a refused form's errors (and what was typed) are shown in its `section`."""
    items = [(i, visibility_of(assignment, i)) for i in logic.item_ids(assignment.lesson, assignment.part)]
    return TEMPLATES.TemplateResponse(request, "setup/assignments.html", {
        "user": user, "a": assignment, "items": items,
        "students": logic.students_view(session=session, assignment=assignment),
        "changes": course_changes.of_course(session=session, course=assignment.course, assignment=assignment),
        "section": section, "errors": errors or [], "v": posted or {}}, status_code=status_code)


def _back(assignment: Assignment, anchor: str) -> RedirectResponse:
    return RedirectResponse(f"/assignments/{assignment.id}#{anchor}", status_code=status.HTTP_303_SEE_OTHER)


@router.get("/assignments/{assignment_id}", response_class=HTMLResponse)
def assignment_page(request: Request, assignment: InstructorsAssignment, session: SessionDep, user: SignedIn):
    return _page(request, session, user, assignment)


@router.get("/assignments/{assignment_id}/grades.csv")
def grades_csv_download(assignment: InstructorsAssignment, session: SessionDep):
    """The counted grades as CSV (the API's export), with the page's sign-in."""
    name, text = exports.counted_grades_csv(session=session, assignment=assignment)
    return PlainTextResponse(text, media_type="text/csv", headers={"Content-Disposition": f'attachment; filename="{name}"'})


@router.post("/assignments/{assignment_id}/release")
def release(assignment: InstructorsAssignment, session: SessionDep, user: SignedIn):
    """Show the withheld (on release) scores and feedback to the students; pressing again changes nothing."""
    logic.release(session=session, assignment=assignment, by=user)
    return _back(assignment, "settings")


@router.post("/assignments/{assignment_id}/extensions", response_class=HTMLResponse)
def grant_extension(request: Request, assignment: InstructorsAssignment, session: SessionDep, user: SignedIn,
                    student: str = Form(""), due_at: str = Form(""), hard_close_at: str = Form("")):
    posted = {"student": student, "due_at": due_at, "hard_close_at": hard_close_at}
    try:
        fields = checked_form(logic.checked_extension, {"student": student.strip()}, posted,
                              ("due_at", "hard_close_at"), assignment.course.timezone)
        logic.grant_extension(session=session, assignment=assignment, student_name=fields["student"],
                              due_at=fields["due_at"], hard_close_at=fields["hard_close_at"], user=user)
    except Invalid as exc:
        session.rollback()
        return _page(request, session, user, assignment, section="extension", errors=exc.errors, posted=posted,
                     status_code=status.HTTP_422_UNPROCESSABLE_CONTENT)
    return _back(assignment, "extensions")


@router.post("/assignments/{assignment_id}/extensions/revoke", response_class=HTMLResponse)
def revoke_extension(request: Request, assignment: InstructorsAssignment, session: SessionDep, user: SignedIn,
                     student: str = Form("")):
    try:
        logic.revoke_extension(session=session, assignment=assignment, student_name=student, by=user)
    except Invalid as exc:
        session.rollback()
        return _page(request, session, user, assignment, section="revoke", errors=exc.errors,
                     status_code=status.HTTP_422_UNPROCESSABLE_CONTENT)
    return _back(assignment, "extensions")
