"""The reconciler: nothing stays lost. Re-sends case runs whose message or worker vanished, and stuck gradings.

- running past its lease (worker crash, machine loss): back to queued with a new attempt number, re-sent;
- queued longer than queue_lease_s (broker restart lost the message): re-sent with a new attempt number;
- grading longer than the lease (grade task lost): the grade task is re-sent (grading is exactly-once anyway).
A new attempt number makes every older message for that case run stale, so a late redelivery never runs twice.
A rocm/cuda case run with no worker of its kind is simply re-sent to the same queue: never to another backend.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from datetime import datetime, timedelta

from sqlalchemy import select
from sqlalchemy.orm import Session

from grader.models import CaseRun, Event, Submission, utcnow
from grader.settings import settings


@dataclass
class Resend:
    case_runs: list[tuple[int, int, str]] = field(default_factory=list)  # (id, attempt, backend)
    gradings: list[int] = field(default_factory=list)


def find_and_requeue(*, session: Session, now: datetime | None = None) -> Resend:
    """Mark what must be re-sent (committed), and return it for the caller to enqueue."""
    now = now or utcnow()
    resend = Resend()
    lost = select(CaseRun).where(CaseRun.status == "running", CaseRun.lease_until < now)
    stale = select(CaseRun).where(CaseRun.status == "queued",
                                  CaseRun.queued_at < now - timedelta(seconds=settings.queue_lease_s))
    for reason, query in (("lease expired", lost), ("message presumed lost", stale)):
        for run in session.scalars(query.with_for_update(skip_locked=True)).all():
            run.status, run.attempt, run.queued_at = "queued", run.attempt + 1, utcnow()
            run.worker = run.worker_pid = run.lease_until = None
            session.add(Event(submission_id=run.submission_id, case_run_id=run.id, state="requeued",
                              detail=f"{reason}; attempt {run.attempt} on queue {run.backend}"))
            resend.case_runs.append((run.id, run.attempt, run.backend))
    stuck = select(Submission).where(Submission.status == "grading",
                                     Submission.grading_at < now - timedelta(seconds=settings.lease_s))
    for submission in session.scalars(stuck).all():
        submission.grading_at = utcnow()
        session.add(Event(submission_id=submission.id, state="grading", detail="grade task re-sent"))
        resend.gradings.append(submission.id)
    session.commit()
    return resend
