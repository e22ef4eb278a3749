"""A student's prediction sheet as a form (grader.services.submissions.sheet_form), for one assignment or their free sheet: the
draft kept on the server, checked by the submission's own rules, imported from and exported to the API's YAML, and
submitted through the same service as the API's POST. For the course's students and instructors; anyone else gets
the not-found page."""

from __future__ import annotations

import hashlib
import json
from typing import Annotated

from fastapi import APIRouter, Depends, File, Request, UploadFile, status
from fastapi.responses import HTMLResponse, PlainTextResponse, RedirectResponse, Response
from starlette.datastructures import FormData

from grader import dispatch
from grader.i18n import N_
from grader.web.deps import SessionDep
from grader.web.errors import status_of, with_retry_after
from grader.core.rubrics import course_rubric
from grader.core.models import Assignment, User, utcnow
from grader.pages.auth import SignedIn
from grader.pages.templates import TEMPLATES
from grader.services.setup import assignments
from grader.services.submissions import drafts, sheets, submit as submissions
from grader.services.submissions import sheet_form as form_logic
from grader.services.errors import DomainError, Invalid, NotFound, Refused
from grader.services.identity import access

router = APIRouter(include_in_schema=False)
# A sheet's YAML is a few kilobytes; the app's body limit (BodyGuard) bounds the upload before this does.
YAML_MAX_BYTES = 256 * 1024


def _writer(user: SignedIn) -> User:
    """Students and instructors fill sheets (the roles that may submit); an auditor gets the not-found page."""
    if not (access.is_student(user) or access.is_instructor(user)):
        raise NotFound("sheet form")
    return user


Writer = Annotated[User, Depends(_writer)]


def _members_assignment(assignment_id: int, session: SessionDep, user: Writer) -> Assignment:
    return assignments.assignment_of(session=session, user=user, assignment_id=assignment_id)


MembersAssignment = Annotated[Assignment, Depends(_members_assignment)]


async def _posted_form(request: Request) -> FormData:
    """The posted fields, all text: a file part where the form has a text input is refused naming the field (422).
    Read here, in the event loop, so that the handlers stay plain functions on the thread pool, as every page's."""
    form = await request.form()
    files = [name for name, value in form.multi_items() if not isinstance(value, str)]
    if files:
        raise Invalid("invalid form", [{"field": name, "rule": "must be text, not a file"} for name in files[:20]])
    return form


Posted = Annotated[FormData, Depends(_posted_form)]


def _path(assignment: Assignment | None) -> str:
    return f"/assignments/{assignment.id}/sheet" if assignment is not None else "/sheet"


def _part_and_lesson(assignment: Assignment | None) -> tuple[str, str]:
    """The items an assignment holds and its lesson; a free sheet answers every item of the one lesson."""
    return (assignment.part, assignment.lesson) if assignment is not None else ("sheet", form_logic.LESSON)


def _starting_sheet(user: User) -> dict:
    return {"lesson": form_logic.LESSON, "student": user.name, "answers": {}}


def _draft_sheet(session, user: User, assignment: Assignment | None) -> dict:
    draft = drafts.load(session=session, user=user, assignment=assignment)
    return draft.sheet if draft is not None else _starting_sheet(user)


def _standing(session, user: User, assignment: Assignment | None) -> dict | None:
    """What a submission now would be: its attempt, lateness and penalty, or the rule that refuses it."""
    if assignment is None:
        return None
    try:
        attempt, late = assignments.admit(session=session, assignment=assignment, student=user, now=utcnow())
    except Refused as exc:
        return {"refused": exc.rule}
    return {"attempt": attempt, "late": assignments.late_text(late),
            "penalty": assignments.penalty_fraction(assignment, late)}


def _book(session, user: User, lesson: str):
    """The course's rubric, read once per request (its session): a post both reads the form and renders the page."""
    books = session.info.setdefault("sheet_form_books", {})
    if (user.course_id, lesson) not in books:
        books[user.course_id, lesson] = course_rubric(session, user.course_id, lesson)
    return books[user.course_id, lesson]


def _render(request: Request, session, user: User, assignment: Assignment | None, sheet: dict, *,
            errors: list[dict] | None = None, checked: bool = False, notice: str | None = None,
            refusal: DomainError | None = None, code: int = status.HTTP_200_OK) -> HTMLResponse:
    part, lesson = _part_and_lesson(assignment)
    if too_large := sheets.size_problems(sheet):  # a draft saved before the caps held: never rendered input by input
        refusal = refusal or Invalid(OVER_CAPS, too_large)
        errors, sheet = refusal.errors, _starting_sheet(user)
    book = _book(session, user, lesson)
    ids = assignments.item_ids(lesson, part)
    items = form_logic.item_forms(book, ids)
    book_configs = book if form_logic.has_configs(part) else None
    configs = ({role: form_logic.config_inputs(book, role, sheet) for role in form_logic.FORM_CONFIGS}
               if book_configs else {})
    checks = []
    if checked and book_configs is not None:
        checks, config_errors = form_logic.config_checks(session=session, sheet=sheet, part=part, book=book)
        shown = {(e["field"], e["rule"]) for e in errors or []}  # a set: one pass, whatever the number of errors
        errors = (errors or []) + [e for e in config_errors if (e["field"], e["rule"]) not in shown]
    names = (["file", "student"] + [i.name for item in items for i in item.inputs]
             + [i.name for inputs in configs.values() for i in inputs])
    placed, unplaced = form_logic.by_input(errors or [], names)
    extra_roles = sorted(set((sheet.get("configs") or {}) if isinstance(sheet.get("configs"), dict) else ())
                         - set(form_logic.FORM_CONFIGS))
    return TEMPLATES.TemplateResponse(request, "submissions/sheet_form.html", {
        "user": user, "a": assignment, "part": part, "lesson": lesson, "path": _path(assignment), "items": items,
        "configs": configs, "rules": {role: book.configs[role] for role in configs}, "extra_roles": extra_roles,
        "values": form_logic.form_state(sheet, items, book_configs), "placed": placed, "unplaced": unplaced,
        "checked": checked, "checks": checks, "notice": notice, "refusal": refusal,
        "standing": _standing(session, user, assignment),
        "has_last": drafts.last_submitted(session=session, user=user, assignment=assignment) is not None,
    }, status_code=code)


OVER_CAPS = "your saved draft cannot be edited in the form; import a corrected YAML"


def _posted_sheet(session, user: User, assignment: Assignment | None, form) -> dict:
    """The sheet the posted form holds over the saved draft. Invalid naming the path when the saved draft is past the
    caps (grader.services.submissions.sheets.size_problems: one saved before they held, or a key the form cannot name): a YAML
    import, or starting from the last submission, replaces it."""
    part, lesson = _part_and_lesson(assignment)
    book = _book(session, user, lesson)
    items = form_logic.item_forms(book, assignments.item_ids(lesson, part))
    previous = _draft_sheet(session, user, assignment)
    sheets.check_size(previous, detail=OVER_CAPS)
    sheet = form_logic.sheet_from_form(form, items=items, book=book if form_logic.has_configs(part) else None,
                                       previous=previous)
    sheet["lesson"] = lesson
    return sheet


def sheet_digest(sheet: dict) -> str:
    """Names the exact draft a confirmation showed, so that "Submit attempt N" submits that draft and no other."""
    return hashlib.sha256(json.dumps(sheet, sort_keys=True, separators=(",", ":")).encode()).hexdigest()[:24]


def _precheck(session, user: User, assignment: Assignment | None, sheet: dict) -> DomainError | None:
    """The refusals a submission now would meet, in the service's order (the assignment's rules, then the sheet's);
    what only submitting can tell (a staff power, a queue's cap) the confirmed submit still answers."""
    if assignment is not None:
        try:
            assignments.admit(session=session, assignment=assignment, student=user, now=utcnow())
        except Refused as exc:
            return exc
    part, _ = _part_and_lesson(assignment)
    problems = form_logic.problems(sheet, part)
    return Invalid("invalid sheet", problems) if problems else None


def _confirmation(request: Request, session, user: User, assignment: Assignment | None, sheet: dict, *,
                  notice: str | None = None) -> HTMLResponse:
    """The step between the form and the submission: the attempt it will be, how late, the penalty, and the two ways
    on (submit this draft, or back to the form with the draft kept)."""
    part, lesson = _part_and_lesson(assignment)
    return TEMPLATES.TemplateResponse(request, "submissions/submit_confirm.html", {
        "user": user, "a": assignment, "part": part, "lesson": lesson, "path": _path(assignment),
        "standing": _standing(session, user, assignment), "digest": sheet_digest(sheet), "notice": notice,
        "questions": len(assignments.item_ids(lesson, part)),
    })


def _confirmed(request: Request, session, user: User, assignment: Assignment | None, form: FormData) -> Response:
    """Submit the saved draft the confirmation named; a draft or attempt changed since is confirmed again."""
    sheet = _draft_sheet(session, user, assignment)
    standing = _standing(session, user, assignment)
    if form.get("digest") != sheet_digest(sheet):
        return _confirmation(request, session, user, assignment, sheet, notice=N_(
            "Your draft changed after this confirmation was shown (another tab or window saved it): "
            "here is the draft as it is now."))
    if standing and standing.get("attempt") and str(standing["attempt"]) != form.get("attempt"):
        return _confirmation(request, session, user, assignment, sheet, notice=N_(
            "Another submission was made meanwhile: this one would now take the attempt named below."))
    try:
        submission = submissions.submit(session=session, user=user, sheet=sheet,
                                        assignment_id=assignment.id if assignment else None, sender=dispatch)
    except NotFound:
        raise
    except DomainError as exc:  # the rule beside the form; the draft stays as it was
        session.rollback()
        return with_retry_after(_render(request, session, user, assignment, sheet, errors=exc.errors, refusal=exc,
                                        code=status_of(exc), checked=True), exc)
    return RedirectResponse(f"/submissions/{submission.id}/progress", status_code=status.HTTP_303_SEE_OTHER)


def _act(request: Request, session, user: User, assignment: Assignment | None, form: FormData) -> Response:
    action = form.get("action") or "save"
    if action == "confirm":  # the confirmation's form carries no answers: it submits the saved draft
        return _confirmed(request, session, user, assignment, form)
    if action == "from_last":
        last = drafts.last_submitted(session=session, user=user, assignment=assignment)
        if last is None:
            raise NotFound("your last submission")
        drafts.save(session=session, user=user, assignment=assignment, sheet=last.sheet)
        return _render(request, session, user, assignment, last.sheet,
                       notice=f"The draft now holds your submission {last.id}'s sheet.")
    sheet = None
    try:
        sheet = _posted_sheet(session, user, assignment, form)
        drafts.save(session=session, user=user, assignment=assignment, sheet=sheet)
    except Invalid as exc:  # past a cap or the saves' quota: the rule above the form, the saved draft as it was
        session.rollback()
        shown = sheet if sheet is not None else _draft_sheet(session, user, assignment)
        return with_retry_after(_render(request, session, user, assignment, shown, errors=exc.errors, refusal=exc,
                                        code=status_of(exc)), exc)
    part, _ = _part_and_lesson(assignment)
    if action == "export":
        name = f"sheet-{assignment.id}.yaml" if assignment is not None else "sheet.yaml"
        return PlainTextResponse(form_logic.sheet_yaml(sheet), media_type="application/yaml",
                                 headers={"Content-Disposition": f'attachment; filename="{name}"'})
    if action == "check":
        problems = form_logic.problems(sheet, part)
        notice = "The sheet passes every rule a submission checks." if not problems else None
        return _render(request, session, user, assignment, sheet, errors=problems, checked=True, notice=notice)
    if action == "submit":  # first the confirmation; a submission it would refuse says the rule beside the form
        refusal = _precheck(session, user, assignment, sheet)
        if refusal is not None:
            return with_retry_after(_render(request, session, user, assignment, sheet, errors=refusal.errors,
                                            refusal=refusal, code=status_of(refusal), checked=True), refusal)
        return _confirmation(request, session, user, assignment, sheet)
    return _render(request, session, user, assignment, sheet, notice="Draft saved.")


def _save_draft(session, user: User, assignment: Assignment | None, form: FormData) -> Response:
    """The page's script saves as the student types; no page comes back, only when it was saved."""
    sheet = _posted_sheet(session, user, assignment, form)
    draft = drafts.save(session=session, user=user, assignment=assignment, sheet=sheet)
    return PlainTextResponse(f"saved {draft.updated_at.isoformat(timespec='seconds')} UTC")


def _import(request: Request, session, user: User, assignment: Assignment | None, file: UploadFile) -> Response:
    data = file.file.read(YAML_MAX_BYTES + 1)
    if len(data) > YAML_MAX_BYTES:
        exc = Invalid("invalid YAML", [{"field": "file", "rule": f"at most {YAML_MAX_BYTES} bytes"}])
    else:
        try:
            sheet = form_logic.sheet_from_yaml(data.decode("utf-8"))
            exc = None
        except UnicodeDecodeError:
            exc = Invalid("invalid YAML", [{"field": "file", "rule": "must be UTF-8 text"}])
        except Invalid as refused:
            exc = refused
    if exc is None:
        try:
            drafts.save(session=session, user=user, assignment=assignment, sheet=sheet)
        except Invalid as refused:  # the saves' quota
            session.rollback()
            exc = refused
    if exc is not None:  # the draft stays as it was
        return with_retry_after(_render(request, session, user, assignment, _draft_sheet(session, user, assignment),
                                        errors=exc.errors, refusal=exc, code=status_of(exc)), exc)
    return _render(request, session, user, assignment, sheet,
                   notice=f"Imported {file.filename or 'the file'} into the draft; check it before submitting.")


@router.get("/assignments/{assignment_id}/sheet", response_class=HTMLResponse)
def assignment_sheet(request: Request, assignment: MembersAssignment, session: SessionDep, user: Writer):
    return _render(request, session, user, assignment, _draft_sheet(session, user, assignment))


@router.post("/assignments/{assignment_id}/sheet", response_class=HTMLResponse)
def assignment_sheet_action(request: Request, assignment: MembersAssignment, session: SessionDep, user: Writer,
                            form: Posted):
    """Save, check, export (YAML), start from the last submission, or submit the form (after its confirmation)."""
    return _act(request, session, user, assignment, form)


@router.post("/assignments/{assignment_id}/sheet/draft")
def assignment_draft(assignment: MembersAssignment, session: SessionDep, user: Writer, form: Posted):
    return _save_draft(session, user, assignment, form)


@router.post("/assignments/{assignment_id}/sheet/import", response_class=HTMLResponse)
def assignment_import(request: Request, assignment: MembersAssignment, session: SessionDep, user: Writer,
                            file: UploadFile = File(...)):
    return _import(request, session, user, assignment, file)


@router.get("/sheet", response_class=HTMLResponse)
def free_sheet(request: Request, session: SessionDep, user: Writer):
    return _render(request, session, user, None, _draft_sheet(session, user, None))


@router.post("/sheet", response_class=HTMLResponse)
def free_sheet_action(request: Request, session: SessionDep, user: Writer, form: Posted):
    return _act(request, session, user, None, form)


@router.post("/sheet/draft")
def free_draft(session: SessionDep, user: Writer, form: Posted):
    return _save_draft(session, user, None, form)


@router.post("/sheet/import", response_class=HTMLResponse)
def free_import(request: Request, session: SessionDep, user: Writer, file: UploadFile = File(...)):
    return _import(request, session, user, None, file)
