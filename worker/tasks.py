"""Thin Celery tasks: ids in, the work in worker.case_run / worker.grading, retries for infrastructure failures only.

A case that fails (wrong backend, crash, timeout) is a result, stored as such, never retried on another backend.
"""

from __future__ import annotations

import logging

from celery.signals import (celeryd_after_setup, worker_init, worker_process_init, worker_process_shutdown,
                            worker_shutdown)
from kombu.exceptions import OperationalError as BrokerError
from sqlalchemy.exc import OperationalError as DatabaseError
from sqlalchemy.orm import Session

from grader.core import lifecycle
from grader.core.db import make_engine, new_session
from grader.core.settings import settings
from grader.core.variants import completion_priority, continue_pool, pool_runs
from worker import grading, slot, warm_gate
from worker.audit import audit_finished_run
from worker.case_run import process_case_run
from worker.celery_app import COMPLETE_QUEUE, GRADE_QUEUE, app

INFRA_ERRORS = (DatabaseError, BrokerError, OSError)
RETRY = dict(autoretry_for=INFRA_ERRORS, max_retries=settings.max_infra_retries, retry_backoff=2,
             retry_backoff_max=60, retry_jitter=True)


@app.task(name="worker.tasks.run_case_run", **RETRY)
def run_case_run(case_run_id: int, delivery: int) -> None:
    with new_session() as session:
        try:
            to_grade = process_case_run(session=session, case_run_id=case_run_id, delivery=delivery,
                                        run_case=slot.run_case_in_slot)
        except INFRA_ERRORS as exc:  # the retry (RETRY) must find the run claimable, not held by this process
            _release(session, case_run_id, delivery, exc)
            raise
    if to_grade is not None:
        grade_submission.apply_async(args=[to_grade], queue=GRADE_QUEUE)
    with new_session() as session:  # the same case queued for other sheets: finished on this measurement now
        alike = lifecycle.finish_alike(session, case_run_id)
    for submission_id in alike:
        grade_submission.apply_async(args=[submission_id], queue=GRADE_QUEUE)
    with new_session() as session:  # after grading was sent: the audit never delays a grade
        audit_finished_run(session, case_run_id)


def _release(session, case_run_id: int, delivery: int, error: BaseException) -> None:
    """Give back this process's claim of the run after an infrastructure error (grader.core.lifecycle.release). If
    the database cannot be reached for that either, the reconciler finds the run held by no live task (liveness)."""
    try:
        session.rollback()
        if lifecycle.release(session, case_run_id, delivery, f"{type(error).__name__} in the worker"):
            session.commit()
    except INFRA_ERRORS:
        logging.getLogger(__name__).exception("could not release case run %s after %r", case_run_id, error)


@app.task(name="worker.tasks.grade_submission", **RETRY)
def grade_submission(submission_id: int) -> None:
    """Store the grade, then send its completion (the lab check) behind the waiting case runs (a pool's measuring
    submission: ahead of the pools' runs, lifecycle.POOL_CHECK_PRIORITY). Sent even when
    the grade was stored already: a redelivery after a crash, or the reconciler re-sending the grade task for a grade
    left incomplete, must still get it completed (completing twice is a no-op)."""
    with new_session() as session:
        grading.grade_submission(session=session, submission_id=submission_id)
        priority = completion_priority(session, submission_id)
    complete_grade.apply_async(args=[submission_id], queue=COMPLETE_QUEUE, priority=priority)
    _continue_pool(submission_id)  # a measuring submission that failed to grade dropped its variant


@app.task(name="worker.tasks.complete_grade", **RETRY)
def complete_grade(submission_id: int) -> None:
    """Add the lab check to a stored grade (worker.grading.complete_grade), once; a pool variant it measures is then
    kept or dropped, and a pool that may no longer keep K is drawn further (grader.core.variants.continue_pool)."""
    with new_session() as session:
        grading.complete_grade(session=session, submission_id=submission_id)
    _continue_pool(submission_id)


def _continue_pool(submission_id: int) -> None:
    """Send what drawing a pool further stored (new measuring runs behind every student's, at POOL_PRIORITY); stored
    and queued if sending fails: the reconciler re-sends it."""
    with new_session() as session:
        runs, grades = continue_pool(session, submission_id)
    for case_run_id, delivery, backend in runs:
        run_case_run.apply_async(args=[case_run_id, delivery], queue=backend, priority=lifecycle.POOL_PRIORITY)
    for measured in grades:
        grade_submission.apply_async(args=[measured], queue=GRADE_QUEUE)


@worker_process_shutdown.connect
def _close_slot(**_) -> None:
    slot.close_slot()


@worker_process_init.connect
def _start_slot(**_) -> None:
    warm_gate.slot_cold()
    slot.start_slot(warm_gate.slot_warm)  # returns at once; the slot's flag is set once its case process is warm


@celeryd_after_setup.connect
def _hold_case_queues(sender, instance, **_) -> None:
    """No case until every slot is warm (worker.warm_gate): the case queues wait, the grade queue is consumed."""
    warm_gate.hold(name=sender, app=instance.app, slots=instance.concurrency)


@worker_shutdown.connect
def _forget_warmth(**_) -> None:
    warm_gate.forget()


@worker_init.connect
def _rerun_what_died_here(**_) -> None:
    """A worker starting where a worker was killed first re-sends the runs the dead processes held, ahead of the
    queue: the killed case is this worker's first, instead of waiting for the reconciler's next pass while the
    worker starts something else (whose warm case process alone takes tens of seconds)."""
    engine = make_engine(settings.database_url)  # its own: the pool processes forked next must inherit no connection
    try:
        with Session(engine) as session:
            todo = []
            for run in lifecycle.dead_here(session):
                lifecycle.requeue(session, run, f"its process {run.worker_pid} on {lifecycle.HOST} is gone "
                                                "(seen by a worker starting there)")
                todo.append((run.id, run.delivery, run.backend))
            pool = pool_runs(session, [case_run_id for case_run_id, _, _ in todo])  # behind students' runs still
            session.commit()
        for case_run_id, delivery, backend in todo:
            priority = lifecycle.POOL_PRIORITY if case_run_id in pool else lifecycle.RERUN_PRIORITY
            run_case_run.apply_async(args=[case_run_id, delivery], queue=backend, priority=priority)
    except INFRA_ERRORS:  # queued in the database or not touched at all: the reconciler re-sends it
        logging.getLogger(__name__).exception("could not re-send the runs of dead processes on %s", lifecycle.HOST)
    finally:
        engine.dispose()
