"""A sheet as the notebook client works on it (grader.services.submissions.notebooks): the caller's assignments, the
sheet page's facts for one (their own lab, the draft, what a submission now would be), the form's Check, the draft the
page keeps, and a submission's progress (queue places and estimates) as the progress page polls it."""

from __future__ import annotations

from typing import Annotated, Any, Literal

from fastapi import APIRouter, Query
from pydantic import BaseModel, Field

from grader.api.responses import errors
from grader.core.models import Assignment
from grader.services.errors import NotFound
from grader.services.identity import access
from grader.services.reports import course_page
from grader.services.setup import assignments
from grader.services.submissions import drafts, notebooks, progress
from grader.web.deps import CurrentUser, RowId, SessionDep

router = APIRouter(tags=["sheets"], responses=errors(401))
Language = Annotated[Literal["en", "zh"], Query(description="The language of questions, words and rules")]


class SheetBody(BaseModel):
    sheet: dict[str, Any] = Field(description="A sheet as POST /v1/submissions takes it (a draft may be incomplete)")


class AssignmentSheetLine(BaseModel):
    id: int
    title: str
    lesson: str
    part: str
    phase: str = Field(description="upcoming | open | late | closed, for the caller (their extension counted)")
    due_at: str
    attempts_used: int
    attempts_left: int | None
    lab: str | None = Field(description="The caller's own lab's parameters where the assignment has variants")


class SheetPublic(BaseModel):
    assignment_id: int
    title: str
    lesson: str
    part: str
    items: list[dict[str, Any]]
    configs: list[dict[str, Any]]
    lab: str | None
    draft: dict[str, Any]
    standing: dict[str, Any] = Field(description="A submission now: attempt, late, penalty; or the rule refusing it")


class CheckPublic(BaseModel):
    passes: bool
    errors: list[dict[str, Any]]
    configs: list[dict[str, Any]]


class DraftPublic(BaseModel):
    saved_at: str


def _assignment(session, user, assignment_id: int) -> Assignment:
    """One of the caller's course's assignments, for the roles that fill sheets (the page's: an auditor gets 404)."""
    if not (access.is_student(user) or access.is_instructor(user)):
        raise NotFound("sheet")
    return assignments.assignment_of(session=session, user=user, assignment_id=assignment_id)


@router.get("/sheets", response_model=list[AssignmentSheetLine], responses=errors(422))
def list_sheets(session: SessionDep, user: CurrentUser, language: Language = "en"):
    """The caller's assignments with their phase, due date, attempts and own lab (a student's course page, as data)."""
    lines = course_page.student_course(session=session, student=user, locale=language)
    return [AssignmentSheetLine(id=line.assignment.id, title=line.assignment.title, lesson=line.assignment.lesson,
                                part=line.assignment.part, phase=line.phase, due_at=line.due_at.isoformat(),
                                attempts_used=line.attempts_used, attempts_left=line.attempts_left,
                                lab=line.lab.summary if line.lab is not None else None) for line in lines]


@router.get("/assignments/{assignment_id}/sheet", response_model=SheetPublic, responses=errors(404, 409, 422))
def get_sheet(assignment_id: RowId, session: SessionDep, user: CurrentUser, language: Language = "en"):
    """The sheet page's facts: items and their fields, config roles and rules, the caller's own lab, the draft the
    page keeps, and what a submission now would be (409 while the caller's lab is being prepared)."""
    view = notebooks.sheet_view(session=session, user=user, assignment=_assignment(session, user, assignment_id),
                                locale=language)
    # the lab's words as the course page says them (its variant fixed by sheet_view, as by the page)
    lab = next((line.lab.summary for line in course_page.student_course(session=session, student=user, locale=language)
                if line.assignment.id == view.assignment.id and line.lab is not None), None)
    return SheetPublic(assignment_id=view.assignment.id, title=view.assignment.title, lesson=view.lesson,
                       part=view.part, items=view.items, configs=view.configs, lab=lab, draft=view.draft,
                       standing=view.standing)


@router.post("/assignments/{assignment_id}/sheet/check", response_model=CheckPublic, responses=errors(404, 409, 422))
def check_sheet(assignment_id: RowId, body: SheetBody, session: SessionDep, user: CurrentUser,
                language: Language = "en"):
    """The sheet form's Check: each error with its field in the caller's words, each config's one-factor verdict
    against the caller's own baseline and the items a broken one voids; nothing is saved."""
    return notebooks.check(session=session, user=user, assignment=_assignment(session, user, assignment_id),
                           sheet=body.sheet, locale=language)


@router.put("/assignments/{assignment_id}/sheet/draft", response_model=DraftPublic, responses=errors(404, 422, 429))
def save_draft(assignment_id: RowId, body: SheetBody, session: SessionDep, user: CurrentUser):
    """Save the draft the sheet page shows (the same one), within the sheet's caps and the draft-save quota."""
    draft = drafts.save(session=session, user=user, assignment=_assignment(session, user, assignment_id),
                        sheet=body.sheet)
    return DraftPublic(saved_at=draft.updated_at.isoformat())


@router.get("/submissions/{submission_id}/progress", response_model=dict[str, Any], responses=errors(404, 422))
def submission_progress(submission_id: RowId, session: SessionDep, user: CurrentUser):
    """Each case run's state and place in its queue, what runs ahead, and estimates: the progress page's data."""
    return progress.as_json(progress.submission_progress(session=session, user=user, submission_id=submission_id))
