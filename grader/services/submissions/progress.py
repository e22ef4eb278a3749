"""A submission's progress while it is graded: where each of its case runs waits in its backend's queue (counted from
the database), how long its cases took when they were measured before, and each run's state; read by the progress
page and its polled JSON (grader.pages.submissions.progress)."""

from __future__ import annotations

import statistics
import time
from dataclasses import dataclass

from sqlalchemy import select
from sqlalchemy.orm import Session

from grader.core import warmth
from grader.core.lifecycle import NEW_PRIORITY, REQUEUED_PRIORITY, fair_priority
from grader.core.states import CaseRunPurpose, CaseRunState, SubmissionState
from grader.core.models import CaseRun, Submission, User
from grader.services.identity import access

# The last runs of one case kept for its median: enough to be steady, few enough to follow a faster worker.
MEASURED_RUNS_KEPT = 50
FINISHED = (SubmissionState.GRADED, SubmissionState.FAILED)


@dataclass(frozen=True)
class RunProgress:
    """One case run of the submission as the progress page shows it."""

    id: int
    name: str
    kind: str
    backend: str
    status: str
    result_status: str | None
    reused: bool  # finished on a stored measurement of the same content key, not run again
    position: int | None  # 1 = next to be drawn from its backend's queue; None unless queued
    waiting: int | None  # runs queued on the same backend, this one included; None unless queued
    typical_s: float | None  # median wall time of this case's earlier real runs on this backend; None: none yet
    measured_runs: int  # how many runs that median is taken over
    wall_s: float | None
    error: str | None

    @property
    def finished(self) -> bool:
        return self.status in (CaseRunState.DONE, CaseRunState.FAILED)


@dataclass(frozen=True)
class WarmingUp:
    """No worker on the queue a run waits on is warm yet, and one is warming up (grader.core.warmth)."""

    for_s: float  # how long the longest-warming of them has been at it
    last_s: float | None  # how long the last finished warm-up took; None: none finished yet


@dataclass(frozen=True)
class Progress:
    submission: Submission
    status: str
    runs: list[RunProgress]
    running_on_backend: dict[str, int]  # runs being run now on each backend this submission waits on
    ahead_s: float | None  # measured case time queued ahead of this submission's first waiting run; None: unknown
    ahead_unmeasured: int  # runs ahead whose case was never measured (not in ahead_s)
    own_s: float | None  # measured case time of this submission's unfinished runs; None: one is unmeasured
    warming_up: "WarmingUp | None" = None  # its runs wait for workers still warming up (none warm on their queue)

    @property
    def finished(self) -> bool:
        """Graded or failed: the report is what to read now."""
        return self.status in FINISHED

    @property
    def counts(self) -> dict[str, int]:
        out = {state.value: 0 for state in CaseRunState}
        for run in self.runs:
            out[run.status] = out.get(run.status, 0) + 1
        return out


def submission_progress(*, session: Session, user: User, submission_id: int) -> Progress:
    """The progress of a submission `user` may read (NotFound for any other, as for its report)."""
    submission = access.readable_submission(session=session, user=user, submission_id=submission_id)
    runs = list(submission.case_runs)
    backends = sorted({r.backend for r in runs if r.status == CaseRunState.QUEUED})
    order = {backend: queue_order(session, backend) for backend in backends}
    places = {run_id: (i + 1, len(ids)) for ids in order.values() for i, run_id in enumerate(ids)}
    typical = {key: _typical(session, *key) for key in {(r.spec_key, r.backend) for r in runs}}
    rows = [_row(r, places.get(r.id), typical[(r.spec_key, r.backend)]) for r in runs]
    ahead_s, unmeasured = _ahead(session, order, rows, typical)
    unfinished = [row for row in rows if not row.finished]
    own = None if any(row.typical_s is None for row in unfinished) else sum(row.typical_s for row in unfinished)
    return Progress(submission=submission, status=submission.status, runs=rows,
                    running_on_backend={b: _running(session, b) for b in backends},
                    ahead_s=ahead_s, ahead_unmeasured=unmeasured, own_s=own, warming_up=warming_up(backends))


def warming_up(backends: list[str]) -> WarmingUp | None:
    """Whether runs queued on `backends` wait for a warm-up: no live worker consuming one of them, one warming up
    that listens on it. None when not (or not knowable: a broker that keeps no record, or one that did not answer)."""
    if not backends:
        return None
    try:
        live = warmth.live()
        if live is None:
            return None
        warm, warming = warmth.warm_backends(live)
        cold = [b for b in backends if b in warming and b not in warm]
        if not cold:
            return None
        last = warmth.last_warm_up_s()
    except Exception:  # noqa: BLE001 - the page must show without this line rather than fail on a broker hiccup
        return None
    since = min(w.started_at for w in live if not w.consuming and set(w.queues) & set(cold))
    return WarmingUp(for_s=max(0.0, time.time() - since), last_s=last)


def _row(run: CaseRun, place: tuple[int, int] | None, typical: tuple[float | None, int]) -> RunProgress:
    return RunProgress(id=run.id, name=run.name, kind=run.kind, backend=run.backend, status=run.status,
                       result_status=run.result_status, reused=run.reused_from_id is not None,
                       position=place[0] if place else None, waiting=place[1] if place else None,
                       typical_s=typical[0], measured_runs=typical[1], wall_s=run.wall_s, error=run.error)


def queue_order(session: Session, backend: str) -> list[int]:
    """The ids of the runs queued on `backend`, in the order a worker draws them: by the priority their message was
    sent at, then by the time they were queued.

    The priority is not stored; it is the one the senders gave, rebuilt from the rows: a re-sent run (delivery > 1)
    the reconciler's REQUEUED_PRIORITY, an audit run NEW_PRIORITY, and a submission's run the fair priority of how many
    of the same student's runs on this backend were waiting or running when it was sent
    (grader.services.submissions.submit._fair_priorities)."""
    queued = session.execute(
        select(CaseRun.id, CaseRun.delivery, CaseRun.purpose, CaseRun.queued_at, Submission.student_id)
        .join(Submission, CaseRun.submission_id == Submission.id)
        .where(CaseRun.backend == backend, CaseRun.status == CaseRunState.QUEUED)).all()
    if not queued:
        return []
    history = _sent_history(session, backend, {row.student_id for row in queued},
                            since=min(row.queued_at for row in queued))
    keyed = []
    for row in queued:
        if row.purpose == CaseRunPurpose.AUDIT:
            priority = NEW_PRIORITY
        elif row.delivery > 1:
            priority = REQUEUED_PRIORITY
        else:
            priority = fair_priority(sum(1 for h in history.get(row.student_id, ()) if _waiting_when_sent(h, row)))
        keyed.append((priority, row.queued_at, row.id))
    return [run_id for _, _, run_id in sorted(keyed)]


def _sent_history(session: Session, backend: str, students: set[int], *, since) -> dict[int, list]:
    """Per student, their grading runs on `backend` that were sent and still waiting or running at `since` or later
    (a run finished at admission on a stored measurement was never sent: it has no start)."""
    rows = session.execute(
        select(CaseRun.id, CaseRun.queued_at, CaseRun.started_at, CaseRun.finished_at, CaseRun.status,
               Submission.student_id)
        .join(Submission, CaseRun.submission_id == Submission.id)
        .where(CaseRun.backend == backend, CaseRun.purpose == CaseRunPurpose.GRADING,
               Submission.student_id.in_(students),
               (CaseRun.finished_at.is_(None)) | (CaseRun.finished_at > since))).all()
    out: dict[int, list] = {}
    for row in rows:
        if row.started_at is None and row.status in (CaseRunState.DONE, CaseRunState.FAILED):
            continue
        out.setdefault(row.student_id, []).append(row)
    return out


def _waiting_when_sent(earlier, run) -> bool:
    """Whether `earlier` waited in the queue (or ran) when `run` was sent: queued before it, not finished by then."""
    return ((earlier.queued_at, earlier.id) < (run.queued_at, run.id)
            and (earlier.finished_at is None or earlier.finished_at > run.queued_at))


def _typical(session: Session, spec_key: str | None, backend: str) -> tuple[float | None, int]:
    """The median wall time of the latest real runs of this case (same physics, spec_key) on `backend`, and how many;
    a run that reused a measurement took no time of its own and is left out."""
    if spec_key is None:
        return None, 0
    walls = list(session.scalars(
        select(CaseRun.wall_s).where(CaseRun.spec_key == spec_key, CaseRun.backend == backend,
                                     CaseRun.status == CaseRunState.DONE, CaseRun.result_status == "ok",
                                     CaseRun.reused_from_id.is_(None), CaseRun.wall_s.is_not(None))
        .order_by(CaseRun.finished_at.desc()).limit(MEASURED_RUNS_KEPT)))
    return (statistics.median(walls), len(walls)) if walls else (None, 0)


def _ahead(session: Session, order: dict[str, list[int]], rows: list[RunProgress],
           typical: dict) -> tuple[float | None, int]:
    """Measured case time queued ahead of this submission's first waiting run on each backend, summed, and how many
    runs ahead have no measurement. (None, 0) when nothing of this submission waits."""
    ahead_ids = []
    for backend, ids in order.items():
        first = min((row.position for row in rows if row.backend == backend and row.position), default=None)
        if first:
            ahead_ids.extend(ids[:first - 1])
    if not any(row.position for row in rows):
        return None, 0
    if not ahead_ids:
        return 0.0, 0
    keys = session.execute(select(CaseRun.spec_key, CaseRun.backend).where(CaseRun.id.in_(ahead_ids))).all()
    total, unmeasured = 0.0, 0
    for key in keys:
        key = (key.spec_key, key.backend)
        if key not in typical:
            typical[key] = _typical(session, *key)
        if typical[key][0] is None:
            unmeasured += 1
        else:
            total += typical[key][0]
    return total, unmeasured


def _running(session: Session, backend: str) -> int:
    return len(session.scalars(select(CaseRun.id).where(CaseRun.backend == backend,
                                                        CaseRun.status == CaseRunState.RUNNING)).all())


def as_json(progress: Progress) -> dict:
    """What the page's script polls: the submission's state, each run's, and where the report is."""
    s = progress.submission
    return {
        "submission_id": s.id, "status": progress.status, "finished": progress.finished,
        "report_url": f"/submissions/{s.id}", "counts": progress.counts,
        "ahead_s": progress.ahead_s, "ahead_unmeasured": progress.ahead_unmeasured, "own_s": progress.own_s,
        "running_on_backend": progress.running_on_backend,
        "warming_up": None if progress.warming_up is None else {"for_s": progress.warming_up.for_s,
                                                                "last_s": progress.warming_up.last_s},
        "runs": [{"id": r.id, "name": r.name, "backend": r.backend, "status": r.status,
                  "result_status": r.result_status, "reused": r.reused, "position": r.position,
                  "waiting": r.waiting, "typical_s": r.typical_s, "measured_runs": r.measured_runs,
                  "wall_s": r.wall_s, "error": r.error} for r in progress.runs],
    }
