"""A submission's progress while it is graded: each of its case runs' state as stored (queued, running, done), where
each waiting run stands in its backend's queue (counted from the database), what is being run ahead of it with the
time it has left, and estimates from measured durations; read by the progress page and its polled JSON
(grader.pages.submissions.progress)."""

from __future__ import annotations

import statistics
import time
from dataclasses import dataclass, field
from datetime import datetime

from sqlalchemy import select
from sqlalchemy.orm import Session

from grader.core import clock, warmth
from grader.core.db import snapshot
from grader.core.lifecycle import NEW_PRIORITY, POOL_PRIORITY, REQUEUED_PRIORITY, fair_priority
from grader.core.models import CaseRun, Submission, User
from grader.core.settings import settings
from grader.core.states import CaseRunPurpose, CaseRunState, ExecutionMode, SubmissionState
from grader.core.variants import measuring_submissions
from grader.services.identity import access
from grader.services.submissions.visibility import grade_view
from rubric.lesson import lesson

# The last measured runs an estimate is taken over: enough to be steady, few enough to follow a faster worker.
MEASURED_RUNS_KEPT = 50
FINISHED = (SubmissionState.GRADED, SubmissionState.FAILED)


@dataclass(frozen=True)
class Estimate:
    """How long a run is expected to take, from measured durations: their median and range over `runs` runs.

    `basis` "case": earlier runs of this very case (same physics) on its backend; "size": a configuration never
    measured, from its size: what a run of its kind (contact, friction) measured on its backend takes besides its
    stepping (the median of their wall time less their stepping time: building or resetting the scene, writing the
    arrays), plus its internal updates (`updates`) times their stepping time per internal update (median; low and high
    from the fastest and slowest per update). A config of 37,500 updates is not a 150-update case (issue 49): measured
    here, N5's 600 updates were estimated within 10% from N1-N4's 75-300. "kind": runs of any case of its kind, where
    neither is known. Only runs that measured a case themselves count
    (not a reused measurement), in the execution mode the run will have; in a warm case process only those that
    reused a built scene, so a process's start, Genesis' import and a first scene build (the warm-up) are left out."""

    median_s: float
    low_s: float
    high_s: float
    runs: int
    basis: str
    updates: int | None = None  # basis "size": the run's own internal updates


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
    estimate: Estimate | None  # None: nothing of its kind was measured on its backend
    running_s: float | None  # how long it has been running; None unless running
    wall_s: float | None
    error: str | None
    withheld: bool = False  # its measurements are withheld from the reader: wall_s, error, reuse and time running
    # are not shown

    @property
    def finished(self) -> bool:
        return self.status in (CaseRunState.DONE, CaseRunState.FAILED)

    @property
    def remaining_s(self) -> float | None:
        """What it still needs by its estimate: all of it while queued, the rest while running (never below 0)."""
        if self.finished or self.estimate is None:
            return None
        return max(0.0, self.estimate.median_s - (self.running_s or 0.0))


@dataclass(frozen=True)
class RunningAhead:
    """A run of someone else being run now on a backend this submission waits on: its slot frees after it."""

    kind: str
    backend: str
    running_s: float
    estimate: Estimate | None

    @property
    def remaining_s(self) -> float | None:
        return None if self.estimate is None else max(0.0, self.estimate.median_s - self.running_s)

    @property
    def overdue(self) -> bool:
        """Running longer than its estimate: what is left is not known."""
        return self.estimate is not None and self.running_s > self.estimate.median_s


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
    running_on_backend: dict[str, int]  # runs being run now on each backend this submission waits on, its own too
    ahead_s: float | None  # estimated case time before this submission's first waiting run; None: nothing waits
    ahead_unmeasured: int  # runs ahead (running or queued) with no estimate or past it (not in ahead_s)
    ahead_never_measured: int  # runs in ahead_s estimated from their size or kind, never measured themselves
    own_s: float | None  # estimated time of this submission's unfinished runs; None: one has no estimate
    running_ahead: list[RunningAhead] = field(default_factory=list)
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

    @property
    def phase(self) -> str:
        """What the submission is doing now, from its runs as they are: graded, failed, grading (every case ran),
        running (one of its runs is being run), waiting (none is: they wait in the queue), or done."""
        if self.finished or self.status == SubmissionState.GRADING:
            return self.status
        counts = self.counts
        if counts[CaseRunState.RUNNING]:
            return "running"
        return "waiting" if counts[CaseRunState.QUEUED] else "done"


def submission_progress(*, session: Session, user: User, submission_id: int) -> Progress:
    """The progress of a submission `user` may read (NotFound for any other, as for its report).

    Its runs' states, the queue order, what runs ahead and the estimates are read in one snapshot of the database
    (grader.core.db.snapshot): read one after another, a run claimed by a worker between two reads was shown queued
    with no place in the queue (issue 49). The caller's transaction so far ends first (see snapshot)."""
    with snapshot(session):
        now = clock.now()
        submission = access.readable_submission(session=session, user=user, submission_id=submission_id)
        runs = list(submission.case_runs)
        estimates = _Estimates(session)
        backends = sorted({r.backend for r in runs if r.status == CaseRunState.QUEUED})
        order = {backend: queue_order(session, backend) for backend in backends}
        places = {run_id: (i + 1, len(ids)) for ids in order.values() for i, run_id in enumerate(ids)}
        # a run whose measurements are withheld from the caller (GradeView.withheld_runs) shows its state and place,
        # not what would match it to another run: its time, error, reuse, nor an estimate from earlier runs of its
        # very case (issue 44, hostile pass 5); its estimate comes from its size or its kind, as for a case never
        # measured
        withheld = grade_view(session=session, submission=submission, user=user, report=False).withheld_runs
        # a withheld run is estimated from its kind alone: its own case's runs would say which case it measured, and
        # its size is an answer (N4's 150 internal updates are C1's; issue 44, hostile pass 13)
        rows = [_row(r, places.get(r.id), estimates.of(None, r.kind, r.backend, r.mode) if r.name in withheld else
                     estimates.of(r.spec_key, r.kind, r.backend, r.mode,
                                  internal_updates(submission.lesson, r.kind, r.spec)),
                     now, withheld=r.name in withheld)
                for r in runs]
        running_ahead = _running_ahead(session, backends, {r.id for r in runs}, estimates, now)
        ahead_s, unmeasured, never = _ahead(session, order, rows, running_ahead, estimates)
        running_on_backend = {b: _running(session, b) for b in backends}
        status = submission.status
    unfinished = [row for row in rows if not row.finished]
    own = None if any(row.estimate is None for row in unfinished) else sum(row.remaining_s for row in unfinished)
    return Progress(submission=submission, status=status, runs=rows, running_on_backend=running_on_backend,
                    ahead_s=ahead_s, ahead_unmeasured=unmeasured, ahead_never_measured=never, own_s=own,
                    running_ahead=running_ahead, warming_up=warming_up(backends))


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


def _elapsed(started_at: datetime | None, now: datetime) -> float:
    return max(0.0, (now - started_at).total_seconds()) if started_at is not None else 0.0


def _row(run: CaseRun, place: tuple[int, int] | None, estimate: Estimate | None, now: datetime, *,
         withheld: bool = False) -> RunProgress:
    running = run.status == CaseRunState.RUNNING
    return RunProgress(id=run.id, name=run.name, kind=run.kind, backend=run.backend, status=run.status,
                       result_status=run.result_status, reused=run.reused_from_id is not None and not withheld,
                       position=place[0] if place else None, waiting=place[1] if place else None,
                       # a withheld run's time running would tell its wall time, and a reuse (never running)
                       estimate=estimate, running_s=_elapsed(run.started_at, now) if running and not withheld else None,
                       wall_s=None if withheld else run.wall_s, error=None if withheld else run.error,
                       withheld=withheld)


def internal_updates(lesson_name: str, kind: str, spec: dict | None) -> int | None:
    """A stored spec's internal updates (outer steps x substeps), as its lesson's case kind derives them; None where
    the lesson's kind says none or the spec does not validate (its run is then estimated by its kind alone)."""
    try:
        model = lesson(lesson_name).case_kinds[kind].model_validate(spec or {})
    except Exception:  # noqa: BLE001 - an estimate is never worth a failed page
        return None
    updates = getattr(model, "internal_updates", None)
    return updates if isinstance(updates, int) and updates > 0 else None


class _Estimates:
    """Estimates by (spec_key, kind, backend, mode), each read once per request."""

    def __init__(self, session: Session):
        self.session, self._cache = session, {}

    def of(self, spec_key: str | None, kind: str, backend: str, mode: str | None,
           updates: int | None = None) -> Estimate | None:
        """The estimate of a run: from earlier runs of the same case, else from its size (`updates`, its internal
        updates) at the measured time per update of its kind, else from runs of cases of its kind."""
        mode = mode or settings.execution_mode  # a run that names no mode runs in the worker's
        if spec_key is not None:
            found = self._get("case", spec_key, backend, mode)
            if found is not None:
                return found
        if updates:
            key = ("size", kind, backend, mode)
            if key not in self._cache:
                self._cache[key] = _size_model(self.session, kind, backend, mode)
            model = self._cache[key]
            if model is not None:
                overhead_s, per_update = model
                return Estimate(median_s=overhead_s + per_update.median_s * updates,
                                low_s=overhead_s + per_update.low_s * updates,
                                high_s=overhead_s + per_update.high_s * updates, runs=per_update.runs, basis="size",
                                updates=updates)
        return self._get("kind", kind, backend, mode)

    def _get(self, basis: str, value: str, backend: str, mode: str) -> Estimate | None:
        key = (basis, value, backend, mode)
        if key not in self._cache:
            self._cache[key] = _estimate(self.session, basis, value, backend, mode)
        return self._cache[key]


def _measured(kind_or_key, backend: str, mode: str):
    """The conditions of a run that measured its case (one case by spec_key, or a kind) as a warm or isolated worker
    would take it again (see Estimate)."""
    return (kind_or_key, CaseRun.backend == backend, CaseRun.status == CaseRunState.DONE,
            CaseRun.result_status == "ok", CaseRun.reused_from_id.is_(None), CaseRun.wall_s.is_not(None),
            CaseRun.provenance["execution_mode"].as_string() == mode)


def _size_model(session: Session, kind: str, backend: str, mode: str) -> tuple[float, Estimate] | None:
    """(what a run of `kind` takes besides stepping, its stepping time per internal update as an Estimate) from the
    latest MEASURED_RUNS_KEPT runs of the kind on `backend` in `mode` that recorded both; None without any. Any scene
    counts (a fresh build is part of what a new config costs); the overhead is a median, so a process's first case
    (Genesis' import and its first build, tens of seconds) is one outlier among them, not the estimate."""
    updates = CaseRun.provenance[("discretization", "internal_updates")].as_integer()
    stepping = CaseRun.provenance[("timings", "steps_s")].as_float()
    rows = session.execute(select(CaseRun.wall_s, updates, stepping)
                           .where(*_measured(CaseRun.kind == kind, backend, mode), updates > 0, stepping.is_not(None))
                           .order_by(CaseRun.finished_at.desc(), CaseRun.id.desc()).limit(MEASURED_RUNS_KEPT)).all()
    if not rows:
        return None
    overhead = statistics.median(max(0.0, wall - steps) for wall, _, steps in rows)
    per_update = [steps / n for _, n, steps in rows]
    return overhead, Estimate(median_s=statistics.median(per_update), low_s=min(per_update), high_s=max(per_update),
                              runs=len(rows), basis="size")


def _estimate(session: Session, basis: str, value: str, backend: str, mode: str) -> Estimate | None:
    """The median and range of the latest MEASURED_RUNS_KEPT measured durations of runs of one case (`basis` "case",
    `value` its spec_key) or one kind of case ("kind"), on `backend`, in execution mode `mode` (see Estimate)."""
    query = select(CaseRun.wall_s).where(*_measured(CaseRun.spec_key == value if basis == "case"
                                                    else CaseRun.kind == value, backend, mode))
    if mode == ExecutionMode.WARM:
        query = query.where(CaseRun.provenance["scene"].as_string() == "reused")
    walls = list(session.scalars(query.order_by(CaseRun.finished_at.desc(), CaseRun.id.desc())
                                 .limit(MEASURED_RUNS_KEPT)))
    if not walls:
        return None
    return Estimate(median_s=statistics.median(walls), low_s=min(walls), high_s=max(walls), runs=len(walls),
                    basis=basis)


def queue_order(session: Session, backend: str) -> list[int]:
    """The ids of the runs queued on `backend`, in the order a worker draws them: by the priority their message was
    sent at, then by the time they were queued.

    The priority is not stored; it is the one the senders gave, rebuilt from the rows: a variant pool's measuring run
    POOL_PRIORITY (sent and re-sent), a re-sent run (delivery > 1) the reconciler's REQUEUED_PRIORITY, an audit run
    NEW_PRIORITY, and a submission's run the fair priority of how many of the same student's runs on this backend were
    waiting or running when it was sent (grader.services.submissions.submit._fair_priorities)."""
    queued = session.execute(
        select(CaseRun.id, CaseRun.delivery, CaseRun.purpose, CaseRun.queued_at, Submission.student_id,
               CaseRun.submission_id.in_(measuring_submissions()).label("pool"))
        .join(Submission, CaseRun.submission_id == Submission.id)
        .where(CaseRun.backend == backend, CaseRun.status == CaseRunState.QUEUED)).all()
    if not queued:
        return []
    history = _sent_history(session, backend, {row.student_id for row in queued},
                            since=min(row.queued_at for row in queued))
    keyed = []
    for row in queued:
        if row.pool:
            priority = POOL_PRIORITY
        elif row.purpose == CaseRunPurpose.AUDIT:
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


def _running_ahead(session: Session, backends: list[str], own: set[int], estimates: _Estimates,
                   now: datetime) -> list[RunningAhead]:
    """Others' runs being run now on `backends`, longest-running first: the slots this submission waits for."""
    if not backends:
        return []
    rows = session.execute(
        select(CaseRun.id, CaseRun.kind, CaseRun.backend, CaseRun.spec_key, CaseRun.mode, CaseRun.started_at,
               CaseRun.spec, Submission.lesson)
        .join(Submission, CaseRun.submission_id == Submission.id)
        .where(CaseRun.backend.in_(backends), CaseRun.status == CaseRunState.RUNNING)
        .order_by(CaseRun.started_at, CaseRun.id)).all()
    return [RunningAhead(kind=r.kind, backend=r.backend, running_s=_elapsed(r.started_at, now),
                         estimate=estimates.of(r.spec_key, r.kind, r.backend, r.mode,
                                               internal_updates(r.lesson, r.kind, r.spec)))
            for r in rows if r.id not in own]


def _ahead(session: Session, order: dict[str, list[int]], rows: list[RunProgress], running: list[RunningAhead],
           estimates: _Estimates) -> tuple[float | None, int, int]:
    """Estimated case time before this submission's first waiting run on each backend: what others' running runs
    still need and the estimates of the runs queued ahead of it, summed; how many of those have no estimate; and how
    many of the summed ones were never measured themselves (estimated from their size or kind). (None, 0, 0) when
    nothing of this submission waits."""
    if not any(row.position for row in rows):
        return None, 0, 0
    ahead_ids = []
    for backend, ids in order.items():
        first = min((row.position for row in rows if row.backend == backend and row.position), default=None)
        if first:
            ahead_ids.extend(ids[:first - 1])
    total, unmeasured, never = 0.0, 0, 0
    for run in running:
        if run.remaining_s is None or run.overdue:  # past its estimate: what it still needs is not known
            unmeasured += 1
        else:
            total += run.remaining_s
            never += run.estimate.basis != "case"
    if ahead_ids:
        for r in session.execute(select(CaseRun.spec_key, CaseRun.kind, CaseRun.backend, CaseRun.mode, CaseRun.spec,
                                        Submission.lesson)
                                 .join(Submission, CaseRun.submission_id == Submission.id)
                                 .where(CaseRun.id.in_(ahead_ids))).all():
            found = estimates.of(r.spec_key, r.kind, r.backend, r.mode, internal_updates(r.lesson, r.kind, r.spec))
            if found is None:
                unmeasured += 1
            else:
                total += found.median_s
                never += found.basis != "case"
    return total, unmeasured, never


def _running(session: Session, backend: str) -> int:
    return len(session.scalars(select(CaseRun.id).where(CaseRun.backend == backend,
                                                        CaseRun.status == CaseRunState.RUNNING)).all())


def _estimate_json(estimate: Estimate | None) -> dict | None:
    if estimate is None:
        return None
    return {"median_s": estimate.median_s, "low_s": estimate.low_s, "high_s": estimate.high_s,
            "runs": estimate.runs, "basis": estimate.basis, "updates": estimate.updates}


def as_json(progress: Progress) -> dict:
    """What the page's script polls: the submission's state, each run's, and where the report is."""
    s = progress.submission
    return {
        "submission_id": s.id, "status": progress.status, "phase": progress.phase, "finished": progress.finished,
        "report_url": f"/submissions/{s.id}", "counts": progress.counts,
        "ahead_s": progress.ahead_s, "ahead_unmeasured": progress.ahead_unmeasured,
        "ahead_never_measured": progress.ahead_never_measured, "own_s": progress.own_s,
        "running_on_backend": progress.running_on_backend,
        "running_ahead": [{"kind": r.kind, "backend": r.backend, "running_s": r.running_s,
                           "remaining_s": r.remaining_s, "estimate": _estimate_json(r.estimate)}
                          for r in progress.running_ahead],
        "warming_up": None if progress.warming_up is None else {"for_s": progress.warming_up.for_s,
                                                                "last_s": progress.warming_up.last_s},
        "runs": [{"id": r.id, "name": r.name, "backend": r.backend, "status": r.status,
                  "result_status": r.result_status, "reused": r.reused, "position": r.position,
                  "waiting": r.waiting, "estimate": _estimate_json(r.estimate), "running_s": r.running_s,
                  "remaining_s": r.remaining_s, "wall_s": r.wall_s, "error": r.error, "withheld": r.withheld}
                 for r in progress.runs],
    }
