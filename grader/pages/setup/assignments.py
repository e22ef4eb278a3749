"""The instructor's page of one assignment: its settings (times in the course's zone), and per student the dates
that apply (their extension, with who granted it), every attempt with its lateness, raw score, late penalty and
counted score, and which attempt counts; and its forms: release the withheld items, grant or revoke a student's
extension (dates typed in the course's zone), each recorded in the course's changes, listed here for this
assignment. Its per-student lab variants (issue 34): generate and measure a pool from a seed before the assignment
opens (K kept, a draw budget, a minimum before students get one), read each variant's parameters, state and why it
was dropped, and add variants at any time (grader.services.setup.variants). For the course's instructors; anyone else gets the 404 page."""

from __future__ import annotations

from fastapi import APIRouter, Form, Request, status
from fastapi.responses import HTMLResponse, PlainTextResponse, RedirectResponse

import rubric
from rubric.variants.texts import parameter_rows

from grader import dispatch
from grader.web.deps import SessionDep
from grader.web.errors import status_of
from grader.core.models import Assignment, User, utcnow
from grader.core.states import PoolState, VariantState
from grader.pages.auth import InstructorsAssignment, SignedIn
from grader.pages.setup.courses import checked_form
from grader.pages.templates import TEMPLATES, request_locale
from grader.services.setup import assignments as logic
from grader.services.setup import course_changes
from grader.services.setup import variants as pools
from grader.services.reports import exports
from grader.services.errors import Conflict, DomainError, Invalid
from grader.services.submissions.visibility import visibility_of

router = APIRouter(include_in_schema=False)


SEED_MAX = 2**31 - 1  # what grader.services.setup.variants.generate accepts


def _page(request: Request, session, user, assignment: Assignment, *, section: str | None = None,
          errors: list[dict[str, str]] | None = None, posted: dict[str, str] | None = None,
          refused: DomainError | None = None, status_code: int = status.HTTP_200_OK) -> HTMLResponse:
    """The page; a refused form's errors (and what was typed), or the service's refusal, are shown in its `section`."""
    items = [(i, visibility_of(assignment, i)) for i in logic.item_ids(assignment.lesson, assignment.part)]
    return TEMPLATES.TemplateResponse(request, "setup/assignments.html", {
        "user": user, "a": assignment, "items": items,
        "students": logic.students_view(session=session, assignment=assignment),
        "changes": course_changes.of_course(session=session, course=assignment.course, assignment=assignment),
        "pool": _pool(session, user, assignment, request_locale(request)), "k_default": pools.K_DEFAULT,
        "k_max": pools.k_max(), "seed_max": SEED_MAX, "opened": assignment.open_at <= utcnow(),
        "spaces": pools.space_versions(session=session, assignment=assignment),
        "section": section, "errors": errors or [], "refused": refused, "v": posted or {}}, status_code=status_code)


def _why_dropped(reason: str | None) -> tuple[str | None, str]:
    """A dropped variant's stored reason (grader.core.variants, grader.services.setup.variants.measure) as a kind the
    page words in the reader's language, and the detail after it (measured evidence, as the service wrote it)."""
    for kind, prefix in (("check_failed", "lab check failed: "), ("screened", "parameters refused before measuring: "),
                         ("not_evaluated", "lab check not evaluated: "), ("failed", "measurement failed: ")):
        if reason and reason.startswith(prefix):
            return kind, reason.removeprefix(prefix)
    return (None, reason or "")


def _pool(session, user: User, assignment: Assignment, locale: str) -> dict | None:
    """The pool as the page shows it: the service's view, and per variant the parameters that differ from the lesson
    (value with unit), every parameter for its details, and why it was dropped (the failed conditions of its lab
    check, from the stored check)."""
    view = pools.pool_view(session=session, assignment=assignment, user=user)
    if view is None:
        return None
    checks = {row.name: row.check for row in pools.pool_of(session, assignment).variants}
    variants = []
    for v in view.variants:
        table = parameter_rows(rubric.Variant(id=v.id, parameters=v.parameters), locale)
        kind, detail = _why_dropped(v.reason) if v.state == VariantState.DROPPED else (None, "")
        failed = [c for c in (checks.get(v.id) or {}).get("conditions", []) if not c.get("passed")]
        variants.append({"v": v, "table": table, "changed": [(name, value) for name, _, value, differs in table
                                                              if differs],
                         "why": kind, "detail": detail, "failed": failed})
    decided = sum(v.state in (VariantState.KEPT, VariantState.DROPPED) for v in view.variants)
    return {"view": view, "variants": variants, "decided": decided, "ready": view.state == PoolState.READY,
            "can_top_up": view.state == PoolState.READY and view.kept < view.k}


def _whole(text: str, field: str, low: int, high: int) -> tuple[int | None, dict | None]:
    """A typed whole number in [low, high], or the error naming the field and the rule."""
    try:
        value = int(text.strip())
    except ValueError:
        value = None
    if value is None or not low <= value <= high:
        return None, {"field": field, "rule": "whole", "low": low, "high": high}
    return value, None


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


@router.post("/assignments/{assignment_id}/variants", response_class=HTMLResponse)
def generate_pool(request: Request, assignment: InstructorsAssignment, session: SessionDep, user: SignedIn,
                  seed: str = Form(""), k: str = Form(""), budget: str = Form(""), minimum: str = Form(""),
                  space_version: str = Form("")):
    """Keep K variants drawn from the seed, and send every variant's lesson runs to the workers (the API's
    POST /v1/assignments/ID/variants, with the page's sign-in); the budget and minimum may be left empty."""
    posted = {"seed": seed, "k": k, "budget": budget, "minimum": minimum, "space_version": space_version}
    (seed_value, seed_error), (k_value, k_error) = _whole(seed, "seed", 0, SEED_MAX), _whole(k, "k", 1, pools.k_max())
    top = (k_value or 1)
    budget_value, budget_error = _whole(budget, "budget", top, pools.BUDGET_FACTOR_MAX * top) if budget.strip() \
        else (None, None)
    minimum_value, minimum_error = _whole(minimum, "minimum", 1, top) if minimum.strip() else (None, None)
    problems = [e for e in (seed_error, k_error, budget_error, minimum_error) if e]
    if problems:
        return _page(request, session, user, assignment, section="variants", posted=posted,
                     errors=problems, status_code=status.HTTP_422_UNPROCESSABLE_CONTENT)
    try:
        pools.generate_and_measure(session=session, assignment=assignment, user=user, seed=seed_value, k=k_value,
                                   budget=budget_value, minimum=minimum_value,
                                   space_version=space_version.strip() or None, sender=dispatch)
    except (Invalid, Conflict) as exc:
        session.rollback()
        return _page(request, session, user, assignment, section="variants", posted=posted, refused=exc,
                     status_code=status_of(exc))
    return _back(assignment, "variants")


@router.post("/assignments/{assignment_id}/variants/top-up", response_class=HTMLResponse)
def top_up_pool(request: Request, assignment: InstructorsAssignment, session: SessionDep, user: SignedIn,
                more: str = Form("")):
    """Draw the pool further from its seed and measure the new variants: MORE variants more to keep (at any time), or
    without it the K - kept a ready pool lacks."""
    more_value = None
    if more.strip():
        more_value, error = _whole(more, "more", 1, pools.k_max())
        if error:
            return _page(request, session, user, assignment, section="top-up", errors=[error], posted={"more": more},
                         status_code=status.HTTP_422_UNPROCESSABLE_CONTENT)
    try:
        pools.top_up(session=session, assignment=assignment, user=user, sender=dispatch, more=more_value)
    except (Invalid, Conflict) as exc:
        session.rollback()
        return _page(request, session, user, assignment, section="top-up", refused=exc, status_code=status_of(exc))
    return _back(assignment, "variants")
