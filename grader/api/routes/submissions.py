"""Submissions: create (sheet with configs), status and progress, grade, case runs with provenance, events."""

from __future__ import annotations

import logging

from fastapi import APIRouter, Depends, HTTPException, status
from pydantic import ValidationError
from sqlalchemy import select
from sqlalchemy.exc import IntegrityError

from grader import assignments, crud, dispatch, sheets
from grader.api.deps import CurrentUser, SessionDep, SubmissionDep
from grader.api.errors import error, field_errors
from grader.api.ratelimit import limit_submissions
from grader.api.responses import errors
from grader.api.views import grade_history_public, grade_public, submission_public
from grader.core import lifecycle
from grader.core.rubrics import current_grade, grade_history
from grader.models import Assignment, Event, utcnow
from grader.schemas import CaseRunPublic, EventPublic, GradeHistoryEntry, GradePublic, SubmissionCreate, SubmissionPublic

log = logging.getLogger(__name__)
router = APIRouter(prefix="/submissions", tags=["submissions"], responses=errors(401))
ONE = errors(404, 422)
NOT_GRADED = errors(409, _409="Not graded yet, or not shown to this student yet (its assignment withholds every "
                                "item's score until the due date or a release); the detail says which")


# NaN/Infinity and deep nesting never reach this handler: grader.api.bodies refuses them for every JSON body.
@router.post("", status_code=status.HTTP_202_ACCEPTED, response_model=SubmissionPublic,
             responses=errors(403, 409, 413, 422, 429, _409=(
                 "Refused by its assignment: not open yet, past its hard close, or no attempt left; the rule "
                 "names the time that applies"), _429=(
                 "Too many submissions: this token's rate, or the assignment's max_per_hour for this student; retry "
                 "after Retry-After seconds")), dependencies=[Depends(limit_submissions)])
def create_submission(body: SubmissionCreate, session: SessionDep, user: CurrentUser):
    """Validate a sheet and its case configs, store the submission and its case runs, then queue every case.
    Each token may submit at most RATE_LIMIT_SUBMISSIONS, and a student at most an assignment's max_per_hour to it
    (429 with Retry-After past either)."""
    if user.role not in ("student", "instructor"):
        raise HTTPException(status.HTTP_403_FORBIDDEN, f"role {user.role} may not submit")
    assignment = None
    if body.assignment_id is not None:
        assignment = session.get(Assignment, body.assignment_id)
        if assignment is None or assignment.course_id != user.course_id:
            return error(422, "unknown assignment", [{"field": "assignment_id",
                                                      "rule": f"no assignment {body.assignment_id} in your course"}])
        try:  # the time and attempt rules come before the sheet: a closed assignment takes nothing
            attempt, late_seconds = assignments.admit(session=session, assignment=assignment, student=user,
                                                      now=utcnow())
        except assignments.Refused as exc:
            if exc.retry_after_s is not None:
                return error(429, "submission refused", [{"field": exc.field, "rule": exc.rule}],
                             headers={"Retry-After": str(exc.retry_after_s)})
            return error(409, "submission refused", [{"field": exc.field, "rule": exc.rule}])
    try:
        sheet = sheets.parse_sheet(body.sheet, assignment.items if assignment else "sheet")
        specs = sheets.cases_to_run(sheet)
    except ValidationError as exc:
        from rubric import describe_errors

        return error(422, "invalid sheet", field_errors(describe_errors(exc), prefix="sheet"))
    if body.backend is not None:
        from rubric import with_backend

        specs = [with_backend(spec, backend=body.backend) for spec in specs]
    if assignment is not None and sheet.lesson != assignment.lesson:
        return error(422, "invalid sheet", [{"field": "sheet.lesson",
                                             "rule": f"assignment {assignment.id} is for lesson {assignment.lesson}"}])
    submission = crud.create_submission(session=session, student=user, lesson=sheet.lesson, sheet=body.sheet,
                                        specs=specs, force_rerun=body.force_rerun)
    if assignment is not None:
        submission.assignment_id, submission.attempt, submission.late_seconds = assignment.id, attempt, late_seconds
    try:
        session.flush()  # a concurrent submission that took this attempt number fails here, before any grading
    except IntegrityError:
        session.rollback()
        return error(409, "submission refused", [{"field": "assignment_id", "rule": (
            f"attempt {attempt} of assignment {assignment.id} was just taken by another submission; submit again")}])
    # A case with a stored measurement is finished now; with none left to run, only the grade task is sent, or a
    # checkpoint sheet (the lesson's own cases only, the same for every student) is graded in this request. While
    # one of its cases was never measured it is queued like any other, so no student loses a point to a gap.
    grading = lifecycle.reuse_at_admission(session=session, submission=submission)
    if grading and sheets.checkpoints_only(sheet):
        assignments.grade_now(session=session, submission=submission, sheet=sheet)
        grading = False
    session.commit()  # nothing is enqueued before the submission and all its case runs are durable
    if grading:
        try:
            dispatch.send_grade(submission.id)
        except Exception:  # stored as 'grading': the reconciler re-sends its grade task after the lease
            log.exception("could not enqueue the grading of submission %s; the reconciler will re-send it",
                          submission.id)
    for run in submission.case_runs:
        if run.status != "queued":  # reused when submitted
            continue
        try:
            dispatch.send_case_run(run.id, run.attempt, run.backend)
        except Exception:  # stored and queued in the database: the reconciler re-sends it
            log.exception("could not enqueue case run %s; the reconciler will re-send it", run.id)
    return submission_public(submission, session, user)


def shown_later(submission, session, user, *, any_item: bool = False) -> dict[str, str]:
    """409 while the submission's assignment withholds every item's score and feedback from this student (with
    `any_item`, while it withholds any); else the items withheld, with why."""
    hidden = assignments.withheld_items(session=session, submission=submission, user=user, now=utcnow())
    why = assignments.withheld(session=session, submission=submission, user=user, now=utcnow())
    if any_item and hidden and not why:
        why = "some items' scores and feedback are " + " and ".join(sorted(set(hidden.values())))
    if why:
        raise HTTPException(status.HTTP_409_CONFLICT, f"grade of submission {submission.id} is withheld: {why}")
    return hidden


@router.get("", response_model=list[SubmissionPublic])
def list_submissions(session: SessionDep, user: CurrentUser):
    """The caller's own submissions (students) or their course's (instructors, auditors)."""
    return [submission_public(s, session, user) for s in crud.visible_submissions(session=session, user=user)]


@router.get("/{submission_id}", response_model=SubmissionPublic, responses=ONE)
def get_submission(submission: SubmissionDep, session: SessionDep, user: CurrentUser):
    """Status and progress of one submission."""
    return submission_public(submission, session, user)


@router.get("/{submission_id}/grade", response_model=GradePublic,
            responses={**ONE, **NOT_GRADED})
def get_grade(submission: SubmissionDep, session: SessionDep, user: CurrentUser):
    """The grade with per-item score, feedback and measured evidence."""
    hidden = shown_later(submission, session, user)
    grade = current_grade(session, submission.id)
    if grade is None:
        detail = f"submission {submission.id} is {submission.status}, not graded"
        raise HTTPException(status.HTTP_409_CONFLICT, detail + (f": {submission.error}" if submission.error else ""))
    return grade_public(grade, assignments.shown_report(grade.report, hidden))


@router.get("/{submission_id}/grades", response_model=list[GradeHistoryEntry], responses={**ONE, **NOT_GRADED})
def list_grades(submission: SubmissionDep, session: SessionDep, user: CurrentUser):
    """Every grade the submission has had, oldest first: the first grading, then one per committed regrade (once
    every item is shown to the caller: the totals would tell a withheld score)."""
    shown_later(submission, session, user, any_item=True)
    return grade_history_public(grade_history(session, submission.id))


@router.get("/{submission_id}/case-runs", response_model=list[CaseRunPublic], responses=ONE)
def list_case_runs(submission: SubmissionDep):
    """Every case run with its state, requested and actual backend, reuse and provenance."""
    return submission.case_runs


@router.get("/{submission_id}/events", response_model=list[EventPublic], responses=ONE)
def list_events(submission: SubmissionDep, session: SessionDep):
    """Every timestamped state change of the submission and its case runs."""
    return session.scalars(select(Event).where(Event.submission_id == submission.id).order_by(Event.id)).all()
