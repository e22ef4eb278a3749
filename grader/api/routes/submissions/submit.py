"""Submissions: create (sheet with configs), status and progress, grade, case runs with provenance, events."""

from __future__ import annotations

from fastapi import APIRouter, Request, Response, status
from sqlalchemy import select

from grader import dispatch
from grader.web import etag
from grader.web.deps import CurrentUser, SessionDep, SubmissionDep
from grader.api.responses import errors
from grader.api.views import case_runs_public, grade_history_public, grade_public, submission_public
from grader.core.grades import grade_history
from grader.core.models import Event
from grader.core.states import CaseRunState
from grader.core.schemas import CaseRunPublic, EventPublic, GradeHistoryEntry, GradePublic, SubmissionCreate, SubmissionPublic
from grader.services.submissions import submit as submissions
from grader.services.errors import Conflict
from grader.services.submissions.visibility import GradeView, attempt_standing, grade_view

router = APIRouter(prefix="/submissions", tags=["submissions"], responses=errors(401))
ONE = errors(404, 422)
NOT_GRADED = errors(409, _409="Not graded yet, or not shown to this student yet (its assignment withholds every "
                                "item's score until the due date or a release); the detail says which")


# NaN/Infinity and deep nesting never reach this handler: grader.web.bodies refuses them for every JSON body.
@router.post("", status_code=status.HTTP_202_ACCEPTED, response_model=SubmissionPublic,
             responses=errors(403, 409, 413, 422, 429, _409=(
                 "Refused by its assignment: not open yet, past its hard close, or no attempt left; the rule "
                 "names the time that applies"), _429=(
                 "Too many submissions: this person's rate (counted for the API and the pages alike), or the "
                 "assignment's max_per_hour for this student; retry after Retry-After seconds")))
def create_submission(body: SubmissionCreate, session: SessionDep, user: CurrentUser):
    """Validate a sheet and its case configs, store the submission and its case runs, then queue every case.
    Each person may submit at most RATE_LIMIT_SUBMISSIONS (through this API and the pages together), and a student
    at most an assignment's max_per_hour to it (429 with Retry-After past either)."""
    submission = submissions.submit(session=session, user=user, sheet=body.sheet, assignment_id=body.assignment_id,
                                     backend=body.backend, force_rerun=body.force_rerun, sender=dispatch)
    return submission_public(submission, session, user)


def _shown(submission, session, user, *, every_item: bool = False) -> GradeView:
    """The grade as the caller may see it; 409 while its assignment withholds every item's score and feedback from
    this student (with `every_item`, while it withholds any)."""
    view = grade_view(session=session, submission=submission, user=user, report=False)  # loaded when read
    why = view.some_withheld if every_item else view.nothing_shown
    if why:
        raise Conflict(f"grade of submission {submission.id} is withheld: {why}")
    return view


@router.get("", response_model=list[SubmissionPublic])
def list_submissions(session: SessionDep, user: CurrentUser):
    """The caller's own submissions (students) or their course's (instructors, auditors)."""
    return [submission_public(s, session, user) for s in submissions.visible_submissions(session=session, user=user)]


CONDITIONAL = {304: {"description": "Not modified: the complete report's ETag matches If-None-Match"}}


def _json(model) -> Response:
    return Response(model.model_dump_json(), media_type="application/json")


@router.get("/{submission_id}", response_model=SubmissionPublic, responses={**ONE, **CONDITIONAL})
def get_submission(request: Request, submission: SubmissionDep, session: SessionDep, user: CurrentUser):
    """Status and progress of one submission. Once its report is complete it carries an ETag, and a matching
    If-None-Match is answered 304 (poll with it)."""
    view = grade_view(session=session, submission=submission, user=user, report=False)
    tag = etag.etag_of("v1-submission", etag.report_state(session, submission, user, view),
                       attempt_standing(session, submission, user, view)) if etag.complete(submission, view) else None
    return etag.conditional(request, tag, lambda: _json(submission_public(submission, session, user)),
                            cache_key="v1-submission", until=tag and etag.shown_until(session, submission, user, view))


@router.get("/{submission_id}/grade", response_model=GradePublic,
            responses={**ONE, **NOT_GRADED, **CONDITIONAL})
def get_grade(request: Request, submission: SubmissionDep, session: SessionDep, user: CurrentUser):
    """The grade with per-item score, feedback and measured evidence; with an ETag once the report is complete
    (304 to a matching If-None-Match)."""
    view = _shown(submission, session, user)
    if view.stored is None:
        detail = f"submission {submission.id} is {submission.status}, not graded"
        raise Conflict(detail + (f": {submission.error}" if submission.error else ""))
    tag = etag.etag_of("v1-grade", etag.report_state(session, submission, user, view)) \
        if etag.complete(submission, view) else None
    return etag.conditional(request, tag, lambda: _json(grade_public(view)), cache_key="v1-grade",
                            until=tag and etag.shown_until(session, submission, user, view))


@router.get("/{submission_id}/grades", response_model=list[GradeHistoryEntry], responses={**ONE, **NOT_GRADED})
def list_grades(submission: SubmissionDep, session: SessionDep, user: CurrentUser):
    """Every grade the submission has had, oldest first: the first grading, then one per committed regrade (once
    every item is shown to the caller: the totals would tell a withheld score)."""
    _shown(submission, session, user, every_item=True)
    return grade_history_public(grade_history(session, submission.id))


@router.get("/{submission_id}/case-runs", response_model=list[CaseRunPublic], responses=ONE)
def list_case_runs(submission: SubmissionDep, session: SessionDep, user: CurrentUser):
    """Every case run with its state, requested and actual backend, reuse and provenance (not the provenance and
    metrics of a run that decides an item withheld from the caller)."""
    return case_runs_public(submission, session, user)


@router.get("/{submission_id}/events", response_model=list[EventPublic], responses=ONE)
def list_events(submission: SubmissionDep, session: SessionDep, user: CurrentUser):
    """Every timestamped state change of the submission and its case runs. A run whose measurements are withheld
    from the caller (GradeView.withheld_runs) keeps its states and times, not its details: how long it took, its
    error and which measurement it reused would match it to another run (issue 44, hostile pass 5), nor its times or
    its running state (pass 6)."""
    withheld = grade_view(session=session, submission=submission, user=user, report=False).withheld_runs
    ids = {r.id for r in submission.case_runs if r.name in withheld}
    # an audit re-run of a withheld run tells what its source would (its time, its validation; pass 14)
    ids |= {r.id for r in submission.audit_runs if r.source_case_run_id in ids}
    events = session.scalars(select(Event).where(Event.submission_id == submission.id).order_by(Event.id)).all()
    # a withheld run's events keep their states, in order, not their times (running -> done is its wall time, and a
    # reused run has no running) nor details; its "running" is left out, so a reuse looks like a run
    # and they come last, together, so that their place among timed events bounds no time either (pass 10)
    events = sorted(events, key=lambda e: e.case_run_id in ids)  # stable: each run's own order kept
    return [EventPublic.model_validate(e).model_copy(update={"detail": "withheld" if e.detail else None, "at": None})
            if e.case_run_id in ids else EventPublic.model_validate(e) for e in events
            if not (e.case_run_id in ids and e.state == CaseRunState.RUNNING)]
