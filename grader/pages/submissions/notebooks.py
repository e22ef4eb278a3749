"""A notebook uploaded on the sheet page (grader.services.submissions.notebooks): its answer cells read, never run,
and, when the service would take the sheet they make, kept as the draft and put before the same confirmation as the
form's Submit; a notebook that is refused keeps the draft as it was and says why beside the form, naming the cell."""

from __future__ import annotations

from fastapi import APIRouter, File, Request, UploadFile
from fastapi.responses import HTMLResponse, Response

from grader.i18n import N_
from grader.core.models import Assignment, User
from grader.pages.submissions import sheet_form as page
from grader.services.errors import Invalid
from grader.services.submissions import drafts, notebooks, sheets
from grader.services.submissions import sheet_form as form_logic
from grader.web.deps import SessionDep
from grader.web.errors import status_of, with_retry_after

router = APIRouter(include_in_schema=False)


def _sheet_of(session, user: User, assignment: Assignment | None, data: bytes) -> dict:
    """The sheet the notebook's cells make for this page (its lesson the assignment's); Invalid naming the file's or
    the cell's problem, or the sheet's rule (the form's Check), each sheet error with its cell."""
    part, lesson = page._part_and_lesson(assignment)
    notebook = notebooks.read(data)
    sheet = notebook.sheet(student=user.name, lesson=lesson)
    sheets.check_size(sheet)  # the sheet's caps before its rules, as every door
    if problems := form_logic.problems(sheet, part):
        raise notebooks.with_cells(Invalid(notebooks.DETAIL, problems), notebook)
    return sheet


def _upload(request: Request, session, user: User, assignment: Assignment | None, file: UploadFile) -> Response:
    data = file.file.read(notebooks.MAX_BYTES + 1)
    try:
        sheet = _sheet_of(session, user, assignment, data)
        drafts.save(session=session, user=user, assignment=assignment, sheet=sheet)
    except Invalid as exc:  # the draft stays as it was
        session.rollback()
        return with_retry_after(page._render(request, session, user, assignment,
                                             page._draft_sheet(session, user, assignment), errors=exc.errors,
                                             refusal=exc, code=status_of(exc), checked=True), exc)
    return page._confirmation(request, session, user, assignment, sheet, notice=N_(
        "Your notebook's answers are now your draft: submit them here, or go back to the form to look at them."))


@router.post("/assignments/{assignment_id}/sheet/notebook", response_class=HTMLResponse)
def assignment_notebook(request: Request, assignment: page.MembersAssignment, session: SessionDep, user: page.Writer,
                        file: UploadFile = File(...)):
    return _upload(request, session, user, assignment, file)


@router.post("/sheet/notebook", response_class=HTMLResponse)
def free_notebook(request: Request, session: SessionDep, user: page.Writer, file: UploadFile = File(...)):
    return _upload(request, session, user, None, file)
