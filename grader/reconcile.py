"""The reconciler: nothing stays lost. Re-sends case runs whose message or worker vanished, and stuck gradings.

- running, but no live worker holds it (its worker was killed; Celery's remote control says which tasks each live
  worker holds): back to queued with a new delivery number, re-sent, without waiting for the lease;
- running on a host whose worker stopped beating: no worker of that host answered and none renewed its record in the
  broker's warmth store (grader.core.warmth: every worker renews it every few seconds, busy or not) within its
  lifetime. A container SIGKILLed, or removed, is such a host: its run is re-queued within a pass or two of the kill,
  not at its lease (17 minutes, issue 46);
- queued, but its queue is empty on the broker and no worker holds it, or the broker lost every message (the marker
  `grader.dispatch.broker_kept_marker` left on it is gone: a restart without persistence): re-sent at once, and so
  are pending gradings;
- where liveness is not knowable (the embedded broker, or no broker answer) the leases decide:
  running past its lease (worker crash, machine loss), or queued longer than queue_lease_s;
- grading longer than the lease (grade task lost): the grade task is re-sent (grading is exactly-once anyway);
- graded, but its lab check still missing a lease after the grade task was sent (the worker died while
  evaluating it): the grade task is re-sent (a "completing" event), and completes the stored grade without grading
  again;
- counted scores marked for the LMS gradebooks (grader.services.lti.outbox) are sent, once the marking commits or the
  backoff after a failed send is over, and withheld ones once their due date passes.
A new delivery number makes every older message for that case run stale, so a late redelivery never runs twice.
A rocm/cuda case run with no worker of its kind is simply re-sent to the same queue: never to another backend.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from datetime import datetime, timedelta
from pathlib import Path

from sqlalchemy import select
from sqlalchemy.orm import Session

from grader.core import lifecycle, warmth
from grader.core.variants import pool_runs
from grader.dispatch import grade_held
from grader.core.models import CaseRun, Event, Grade, Submission, utcnow
from grader.services.lti import outbox as lti_outbox
from grader.core.settings import settings
from grader.core.states import CaseRunState, SubmissionState

# A run younger than this is never judged by liveness: its message may be between the broker and a worker.
LIVENESS_GRACE_S = 10.0
# How often the shipped reconcilers pass (embedded service, docker-compose): a killed worker's run is re-queued
# within about RECONCILE_EVERY_S of the kill on its own host (a dead pid needs no grace), LIVENESS_GRACE_S +
# RECONCILE_EVERY_S from another host; a worker starting on that host re-queues it at once (worker.tasks).
RECONCILE_EVERY_S = 15.0
# Where the broker did not answer (down, restarting), the next pass comes this soon instead of a whole interval.
UNKNOWN_RETRY_S = 2.0


@dataclass
class Resend:
    case_runs: list[tuple[int, int, str]] = field(default_factory=list)  # (id, delivery, backend)
    were_running: set[int] = field(default_factory=set)  # ids among case_runs whose worker died: they go first
    pool_runs: set[int] = field(default_factory=set)  # ids among case_runs measuring a variant pool: they go last
    gradings: list[int] = field(default_factory=list)
    scores: list[lti_outbox.OutboxPass] = field(default_factory=list)  # sent to the LMS gradebooks in this pass


def _host(worker_name: str) -> str:
    return worker_name.split("@", 1)[-1]


def orphaned(session: Session, now: datetime, liveness, broker_lost: bool = False,
             beating: set[str] | None = None) -> list[tuple[CaseRun, str]]:
    """Runs no live worker holds, by the broker's answer (`grader.dispatch.held_tasks`), with the reason.

    broker_lost: the broker lost every message (`grader.dispatch.broker_kept_marker`), so no queued run's message
    can be trusted to be there, however full its queue is again.
    beating: the hosts with a worker whose warmth record is live (`beating_hosts`); None where it is not known."""
    held_by, depths = liveness
    held = set().union(*held_by.values()) if held_by else set()
    hosts = {_host(name) for name in held_by}
    grace = now - timedelta(seconds=LIVENESS_GRACE_S)
    found = []
    running = select(CaseRun).where(CaseRun.status == CaseRunState.RUNNING, CaseRun.started_at < grace)
    for run in session.scalars(running.with_for_update(skip_locked=True)).all():
        # Judged only where the claiming host has a worker that answered: a silent host may be busy, not dead,
        # and is left to its lease.
        if (run.id, run.delivery) not in held and run.worker in hosts:
            found.append((run, f"no live worker holds it (worker {run.worker} pid {run.worker_pid} is gone)"))
        elif run.worker not in hosts and beating is not None and run.worker not in beating:
            found.append((run, f"its worker stopped beating (no worker on {run.worker} answered or renewed its "
                               f"record for over {warmth.RECORD_TTL_S:.0f} s)"))
    # After a loss no queued run's message is trusted, however young: a duplicate is dropped as stale when claimed.
    queued = select(CaseRun).where(CaseRun.status == CaseRunState.QUEUED, CaseRun.queued_at < (now if broker_lost else grace))
    for run in session.scalars(queued.with_for_update(skip_locked=True)).all():
        if (run.id, run.delivery) in held:
            continue
        if broker_lost:
            found.append((run, "its message is gone (the broker lost its messages: restarted without them)"))
        elif depths.get(run.backend) == 0:
            found.append((run, f"its message is gone (queue {run.backend} is empty and no worker holds it)"))
    return found


def _lost_gradings(session: Session, query, now: datetime, liveness, broker_lost: bool) -> list[tuple[Submission, str]]:
    """Submissions of `query` whose grade task is lost, with the reason (see find_and_requeue)."""
    if broker_lost and liveness is not None:
        return [(s, "the broker lost its messages") for s in session.scalars(query).all()]
    lease = now - timedelta(seconds=settings.lease_s)
    found = [(s, "lease expired") for s in session.scalars(query.where(Submission.grading_at < lease)).all()]
    if liveness is not None:
        # lazy: the queue's name is the worker's; Celery loads only where liveness was asked of it
        from worker.celery_app import GRADE_QUEUE

        held_by, depths = liveness
        held = set().union(*held_by.values()) if held_by else set()
        if depths.get(GRADE_QUEUE) == 0:
            young = now - timedelta(seconds=LIVENESS_GRACE_S)
            found += [(s, f"no live worker holds it and queue {GRADE_QUEUE} is empty") for s in session.scalars(
                query.where(Submission.grading_at < young, Submission.grading_at >= lease)).all()
                if grade_held(s.id) not in held]
    return found


def _last_pass_file() -> Path:
    return settings.data_dir.absolute() / "reconciler" / "last-pass"


def mark_pass(now: float | None = None) -> None:
    """A pass finished: its time goes to a file of this host's (the reconciler container's health check reads it)."""
    path = _last_pass_file()
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(f"{time.time() if now is None else now:.3f}")


def last_pass_age_s(now: float | None = None) -> float | None:
    """Seconds since this host's reconciler last finished a pass; None if it never did."""
    try:
        return (time.time() if now is None else now) - float(_last_pass_file().read_text())
    except (OSError, ValueError):
        return None


def beating_hosts() -> set[str] | None:
    """The hosts with a worker that renewed its warmth record within its lifetime; None where the broker keeps no
    records or did not answer."""
    try:
        workers = warmth.live()
    except Exception:  # noqa: BLE001 - a broker that does not answer says nothing about heartbeats: leases decide
        return None
    return None if workers is None else {_host(w.name) for w in workers}


def find_and_requeue(*, session: Session, now: datetime | None = None, liveness=None,
                     broker_lost: bool = False, beating: set[str] | None = None) -> Resend:
    """Mark what must be re-sent (committed), and return it for the caller to enqueue.

    `liveness` is `grader.dispatch.held_tasks()`'s answer, or None where it is not knowable (leases only);
    `beating` is `beating_hosts()`'s, asked with it (used only where liveness is known).
    `broker_lost`: the broker lost its messages; queued runs and pending gradings are re-sent without their leases."""
    now = now or utcnow()
    resend = Resend()
    lost = select(CaseRun).where(lifecycle.lease_expired(now))
    stale = select(CaseRun).where(lifecycle.queue_lease_expired(now))
    todo = orphaned(session, now, liveness, broker_lost, beating) if liveness is not None else []
    todo += [(run, f"its process {run.worker_pid} on {lifecycle.HOST} is gone") for run in lifecycle.dead_here(session)
             if run.id not in {r.id for r, _ in todo}]
    for reason, query in (("lease expired", lost), ("message presumed lost", stale)):
        todo += [(run, reason) for run in session.scalars(query.with_for_update(skip_locked=True)).all()
                 if run.id not in {r.id for r, _ in todo}]
    for run, reason in todo:
        if run.status == CaseRunState.RUNNING:
            resend.were_running.add(run.id)
        lifecycle.requeue(session, run, reason)
        resend.case_runs.append((run.id, run.delivery, run.backend))
    resend.pool_runs = pool_runs(session, [run.id for run, _ in todo])
    # A grade task is re-sent (grading happens exactly once whatever the duplicates) when it went with the broker, when
    # no live worker holds it and the grade queue is empty (its worker was killed holding it: the message waits in
    # the broker's unacknowledged set for the visibility timeout), or past its lease where liveness is not knowable.
    # grading_at is when the grade task was last sent: re-sending it starts the lease again.
    awaiting = select(Submission).where(Submission.status == SubmissionState.GRADING)
    incomplete = (select(Submission).join(Grade, Grade.submission_id == Submission.id)
                  .where(Submission.status == SubmissionState.GRADED, Grade.superseded_at.is_(None),
                         Grade.completed_at.is_(None)))
    for query, state, detail in ((awaiting, SubmissionState.GRADING, "grade task re-sent"),
                                 (incomplete, "completing",
                                  "grade task re-sent: the grade is stored, its lab check is not")):
        for submission, why in _lost_gradings(session, query, now, liveness, broker_lost):
            submission.grading_at = utcnow()
            session.add(Event(submission_id=submission.id, state=state, detail=f"{detail} ({why})"))
            resend.gradings.append(submission.id)
    session.commit()
    # After the commit: what is re-sent above is marked before any LMS is waited on.
    resend.scores = lti_outbox.send_due(session=session, now=now)
    return resend
