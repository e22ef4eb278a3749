"""Submit a Jupyter notebook: its tagged answer cells read as a sheet (grader.services.submissions.notebooks), never
executed, and submitted through the same service as a sheet's POST."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, File, Form, UploadFile, status

from grader import dispatch
from grader.api.responses import errors
from grader.api.views import submission_public
from grader.core.schemas import ErrorBody, SubmissionPublic
from grader.services.identity.access import MAX_ID
from grader.services.submissions import notebooks
from grader.web.deps import CurrentUser, SessionDep

# Not under /submissions: `/submissions/notebook` would also name a submission for GET /submissions/{submission_id}.
# A multipart body the form parser cannot read is refused before the handler (Starlette's 400).
MALFORMED = {400: {"model": ErrorBody, "description": "A multipart body that cannot be parsed"}}
router = APIRouter(prefix="/notebooks", tags=["submissions"], responses=errors(401))


@router.post("", status_code=status.HTTP_202_ACCEPTED, response_model=SubmissionPublic,
             responses=errors(403, 409, 413, 422, 429, _409=(
                 "Refused by its assignment: not open yet, past its hard close, or no attempt left"), _422=(
                 "Not a notebook this service reads (not JSON, not nbformat 4, outputs too large, no answer cell, two "
                 "cells for one item, a cell that is not one literal assignment), or its sheet breaks a rule; each "
                 "error names the cell")) | MALFORMED)
def submit_notebook(session: SessionDep, user: CurrentUser,
                    file: Annotated[UploadFile, File(description="The .ipynb file, answer cells tagged answer:ID")],
                    assignment_id: Annotated[int | None, Form(ge=1, le=MAX_ID)] = None):
    """Submit a notebook (.ipynb, nbformat 4) whose code cells tagged `answer:ID` and `config:ROLE` each assign one
    literal (`A2 = {"direction": "decrease"}`); read, never run, then submitted as that sheet under every rule of
    POST /v1/submissions (docs/student.md, examples/l03/sheet.ipynb)."""
    data = file.file.read(notebooks.MAX_BYTES + 1)
    submission = notebooks.submit(session=session, user=user, data=data, assignment_id=assignment_id, sender=dispatch)
    return submission_public(submission, session, user)
