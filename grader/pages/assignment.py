"""The instructor's page of one assignment: its settings (times in the course's zone), and per student the dates
that apply (their extension, with who granted it), every attempt with its lateness, raw score, late penalty and
counted score, and which attempt counts. For the course's instructors; anyone else gets the 404 page."""

from __future__ import annotations

from fastapi import APIRouter, Request
from fastapi.responses import HTMLResponse, PlainTextResponse

from grader.api.deps import SessionDep
from grader.pages.auth import InstructorsAssignment, SignedIn
from grader.pages.templates import TEMPLATES
from grader.services import assignments as logic
from grader.services import exports
from grader.services.visibility import visibility_of

router = APIRouter(include_in_schema=False)


@router.get("/assignments/{assignment_id}", response_class=HTMLResponse)
def assignment_page(request: Request, assignment: InstructorsAssignment, session: SessionDep, user: SignedIn):
    items = [(i, visibility_of(assignment, i)) for i in logic.item_ids(assignment.lesson, assignment.part)]
    return TEMPLATES.TemplateResponse(request, "assignment.html", {
        "user": user, "a": assignment, "items": items, "students": logic.students_view(session=session, assignment=assignment)})


@router.get("/assignments/{assignment_id}/grades.csv")
def grades_csv_download(assignment: InstructorsAssignment, session: SessionDep):
    """The counted grades as CSV (the API's export), with the page's sign-in."""
    name, text = exports.counted_grades_csv(session=session, assignment=assignment)
    return PlainTextResponse(text, media_type="text/csv", headers={"Content-Disposition": f'attachment; filename="{name}"'})
