"""Submissions: storing one with its case runs, taking one through its assignment's rules, listing what a user may
read. The API's POST and the browser's submit both go through `submit`, which counts the person's submission rate
for every door."""

from __future__ import annotations

import logging
from typing import Any

from pydantic import ValidationError
from sqlalchemy import func, select
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from grader.core import grading, lifecycle
from grader.core.rubrics import course_rubric
from grader.core.states import Backend, CaseRunState
from grader.core.models import Assignment, CaseRun, Course, Submission, User, utcnow
from grader.core.submissions import create_submission
from grader.services.setup import assignments, student_variants
from grader.core.variants import as_variant
from grader.services.identity import quotas
from grader.services.submissions import sheets
from grader.services.errors import Conflict, Forbidden, Invalid, Refused, field_errors
from grader.services.sending import Sender
from grader.core.settings import settings
from grader.services.identity import access
from rubric import describe_errors, with_backend

log = logging.getLogger(__name__)


def visible_submissions(*, session: Session, user: User, course: Course | None = None):
    """What user may list: a student their own, instructors and auditors their course's."""
    query = select(Submission).order_by(Submission.id)
    if access.is_student(user):
        return session.scalars(query.where(Submission.student_id == user.id)).all()
    return session.scalars(query.where(Submission.course_id == (course or user.course).id)).all()


def submit(*, session: Session, user: User, sheet: dict[str, Any], assignment_id: int | None = None,
           backend: str | None = None, force_rerun: bool = False, sender: Sender) -> Submission:
    """Validate a sheet and its case configs, store the submission and its case runs in one transaction, then send
    every case still to run (`sender`). Raises Forbidden (the role), Refused (the person's submission rate,
    settings.rate_limit_submissions, counted for every door here; the assignment's rules), or Invalid (the sheet's
    size, checked before any work; the sheet; the assignment), and nothing is stored then.

    A case with a stored measurement is finished at once; with none left to run only the grade task is sent, or a
    checkpoint sheet (the lesson's own cases only, the same for every student) is graded in this call. While one of
    its cases was never measured it is queued like any other, so no student loses a point to a gap."""
    if not (access.is_student(user) or access.is_instructor(user)):
        raise Forbidden(f"role {user.role} may not submit")
    # Every door (the API, the sheet form, the command line through the API) counts here, before any work; a refused
    # one is not counted. Refused -> 429 with Retry-After, the same rule on every door.
    quotas.take("submissions", user.id, settings.rate_limit_submissions, field="submissions")
    sheets.check_size(sheet)
    if assignment_id is None and access.is_student(user) and not user.course.free_submissions:
        raise Refused("assignment_id", f"course {user.course.name} takes a student's submission only to an "
                                       "assignment (free_submissions is off): name one in assignment_id")
    assignment = None
    attempt = late_seconds = None
    if assignment_id is not None:
        assignment = session.get(Assignment, assignment_id)
        if assignment is None or assignment.course_id != user.course_id:
            raise Invalid("unknown assignment", [{"field": "assignment_id",
                                                  "rule": f"no assignment {assignment_id} in your course"}])
        # the time and attempt rules come before the sheet: a closed assignment takes nothing
        attempt, late_seconds = assignments.admit(session=session, assignment=assignment, student=user, now=utcnow())
    # The student's own lab at an assignment with a variant pool (fixed at their first visit); None: the shipped one,
    # which is also what staff submitting there work on (as their form shows), never a variant taken from the pool.
    variant = (student_variants.variant_for(session=session, assignment=assignment, student=user)
               if assignment is not None and access.is_student(user) else None)
    if assignment is not None and (not isinstance(sheet, dict) or sheet.get("lesson") != assignment.lesson):
        # first: a sheet of another lesson is refused for that, not for every answer its lesson's model lacks
        raise Invalid("invalid sheet", [{"field": "sheet.lesson",
                                         "rule": f"assignment {assignment.id} is for lesson {assignment.lesson}"}])
    try:
        parsed = sheets.parse_sheet(sheet, assignment.part if assignment else "sheet")
        book = course_rubric(session, user.course_id, parsed.lesson)
        specs = sheets.cases_to_run(parsed, book, as_variant(variant) if variant is not None else None)
    except ValidationError as exc:

        raise Invalid("invalid sheet", field_errors(describe_errors(exc), prefix="sheet")) from None
    if not access.is_instructor(user):
        _refuse_staff_powers(parsed, backend=backend, force_rerun=force_rerun)
    if backend is not None:
        specs = [with_backend(spec, backend=backend) for spec in specs]
    submission = create_submission(session=session, student=user, lesson=parsed.lesson, sheet=sheet, specs=specs,
                                   force_rerun=force_rerun)
    if assignment is not None:
        submission.assignment_id, submission.attempt, submission.late_seconds = assignment.id, attempt, late_seconds
        submission.variant_id = variant.id if variant is not None else None
    try:
        session.flush()  # a concurrent submission that took this attempt number fails here, before any grading
    except IntegrityError:
        session.rollback()
        raise Refused("assignment_id", f"attempt {attempt} of “{assignment.title}” was just taken by another "
                                       f"submission; submit again", reason="attempt_taken",
                      facts={"assignment": assignment.title, "attempt": attempt}) from None
    to_grade = lifecycle.reuse_at_admission(session=session, submission=submission)
    to_send = [run for run in submission.case_runs if run.status == CaseRunState.QUEUED]  # the rest were reused
    _refuse_unserved_backends(to_send, sender)
    priorities = _fair_priorities(session, user, submission, to_send)
    if to_grade and sheets.checkpoints_only(parsed):
        grading.grade_and_store(session=session, submission=submission, book=book, complete=True, detail=(
            "graded at once: no case run needed, the lesson's cases as already measured"))
        to_grade = False
    session.commit()  # nothing is sent before the submission and all its case runs are durable
    if to_grade:
        try:
            sender.send_grade(submission.id)
        except Exception:  # stored as 'grading': the reconciler re-sends its grade task after the lease
            log.exception("could not enqueue the grading of submission %s; the reconciler will re-send it",
                          submission.id)
    for run in to_send:
        try:
            sender.send_case_run(run.id, run.delivery, run.backend, priority=priorities[run.id])
        except Exception:  # stored and queued in the database: the reconciler re-sends it
            log.exception("could not enqueue case run %s; the reconciler will re-send it", run.id)
    return submission


def _refuse_staff_powers(sheet, *, backend: str | None, force_rerun: bool) -> None:
    """A backend choice and a forced re-run queue runs no reuse can shorten, on queues a course may not serve: staff
    powers. A student's runs go to the cpu queue and reuse what is already measured."""
    rules = []
    if backend is not None:
        rules.append({"field": "backend", "rule": "only staff choose the backend; leave it out"})
    if force_rerun:
        rules.append({"field": "force_rerun", "rule": "only staff force a re-run; leave it false"})
    for role, spec in sheet.configs.submitted().items():
        if spec.backend != Backend.CPU:
            rules.append({"field": f"sheet.configs.{role}.backend",
                          "rule": "only staff choose the backend; leave it out (cpu)"})
    if rules:
        raise Forbidden("a student's submission runs on the cpu queue and reuses measurements", rules)


def _refuse_unserved_backends(runs: list[CaseRun], sender: Sender) -> None:
    """A run on a GPU queue no worker consumes would wait forever: refused at once, as an audit re-run is. The cpu
    queue is the service's own and is not asked about (asking costs a broadcast of up to a second per submission).
    Where the broker cannot be asked, the runs are stored and the reconciler sends them once it answers."""
    for backend in sorted({run.backend for run in runs} - {Backend.CPU}):
        try:
            listening = sender.queue_listeners(backend)
        except Exception:  # noqa: BLE001 - an unreachable broker says nothing about workers; refuse nothing
            log.warning("could not ask the broker who listens on queue %s; storing the runs", backend, exc_info=True)
            continue
        if not listening:
            raise Conflict(f"no worker is listening on queue '{backend}': its case runs would wait forever; "
                           f"start a worker with `grader worker --queue {backend}` or choose another backend",
                           [{"field": "backend", "rule": f"a worker must listen on queue '{backend}'"}])


def _fair_priorities(session: Session, user: User, submission: Submission, runs: list[CaseRun]) -> dict[int, int]:
    """Each new run's place in its queue by how many of the student's own runs wait ahead of it
    (lifecycle.fair_priority), after refusing a student past settings.student_waiting_runs_max."""
    waiting = dict(session.execute(
        select(CaseRun.backend, func.count()).join(Submission, CaseRun.submission_id == Submission.id)
        .where(Submission.student_id == user.id, Submission.id != submission.id,
               CaseRun.status.in_((CaseRunState.QUEUED, CaseRunState.RUNNING)))
        .group_by(CaseRun.backend)).all())
    limit = settings.student_waiting_runs_max
    if access.is_student(user) and sum(waiting.values()) + len(runs) > limit:
        raise Refused("sheet", f"{sum(waiting.values())} of your case runs are still waiting or running and this "
                               f"sheet needs {len(runs)} more; at most {limit} at once: submit again when some finish")
    priorities = {}
    for run in runs:
        priorities[run.id] = lifecycle.fair_priority(waiting.get(run.backend, 0))
        waiting[run.backend] = waiting.get(run.backend, 0) + 1
    return priorities
