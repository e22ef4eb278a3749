"""An assignment's variant pool (issue 34): generate and measure (instructors), list with states and reasons, and
the copy evidence stored at grading (staff)."""

from __future__ import annotations

from fastapi import APIRouter, status

from grader import dispatch
from grader.api.responses import errors
from grader.api.routes.setup.assignments import InstructorsAssignment, ReadableAssignment
from grader.api.schemas import VariantPoolCreate, VariantPoolTopUp
from grader.services.setup import variants as logic
from grader.services.setup.variants import FlagRow, PoolView
from grader.web.deps import CurrentUser, SessionDep, StaffUser

router = APIRouter(tags=["assignments"], responses=errors(401, 404, 422))


@router.post("/assignments/{assignment_id}/variants", status_code=status.HTTP_201_CREATED, response_model=PoolView,
             responses=errors(403, 409, 413, 429, _409="The assignment has opened, or has a pool already",
                              _429="The instructor or the course has as many pools measuring as the service allows"))
def generate_pool(assignment: InstructorsAssignment, body: VariantPoolCreate, session: SessionDep, user: CurrentUser):
    """Draw K variants from the seed and queue every variant's lesson runs (an instructor of the course, before the
    assignment opens); each is kept or dropped, with its reason, once its lab check has run, and the pool draws further
    until K are kept or its draw budget is spent (its `outcome` says which)."""
    pool = logic.generate_and_measure(session=session, assignment=assignment, user=user, seed=body.seed, k=body.k,
                                      budget=body.budget, minimum=body.minimum, space_version=body.space_version,
                                      sender=dispatch)
    return logic.pool_view(session=session, assignment=pool.assignment, user=user)


@router.post("/assignments/{assignment_id}/variants/top-up", response_model=PoolView,
             responses=errors(403, 409, 429, _409="Without `more`: still measuring, or K kept already",
                              _429="The instructor or the course has as many pools measuring as the service allows"))
def top_up_pool(assignment: InstructorsAssignment, session: SessionDep, user: CurrentUser,
                body: VariantPoolTopUp | None = None):
    """Draw the pool further from its seed and measure the new variants, at any time (an instructor of the course):
    `more` variants more to keep, or the K - kept a ready pool lacks. Students keep their variant; new students are
    spread over every kept one."""
    logic.top_up(session=session, assignment=assignment, user=user, sender=dispatch,
                 more=body.more if body is not None else None)
    return logic.pool_view(session=session, assignment=assignment, user=user)


@router.get("/assignments/{assignment_id}/variants", response_model=PoolView | None, responses=errors(403))
def list_pool(assignment: ReadableAssignment, session: SessionDep, user: StaffUser):
    """The assignment's pool: every variant's parameters, state (measuring, kept, dropped) and reason (staff); null
    when it has none (its students all work on the lesson's shipped cases)."""
    return logic.pool_view(session=session, assignment=assignment, user=user)


@router.get("/assignments/{assignment_id}/copy-flags", response_model=list[FlagRow], responses=errors(403))
def list_copy_flags(assignment: ReadableAssignment, session: SessionDep, user: StaffUser):
    """Submissions whose answers fit another variant's expected answers rather than their own, with the items and
    that variant (staff; never changes a grade)."""
    return logic.copy_flags(session=session, assignment=assignment, user=user)
