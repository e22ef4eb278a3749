"""What an operator watches: queue depth per queue, case runs by state and backend, case durations, failures by
reason, stuck runs, live workers and their warm case slots.
Served as Prometheus metrics (`GET /metrics`, prometheus_client) and printed
by `grader status`; both read `service_status`, so they never disagree."""

from __future__ import annotations

import time
from collections import Counter

from prometheus_client.core import GaugeMetricFamily, HistogramMetricFamily
from pydantic import BaseModel
from sqlalchemy import func, select
from sqlalchemy.orm import Session

from grader import dispatch
from grader.core.models import CaseRun, Grade, LtiOutbox, Submission, utcnow
from grader.core import lifecycle, warmth
from grader.core.states import CaseRunState

DURATION_BUCKETS_S = (1, 2, 5, 10, 20, 30, 60, 120, 300, 600, 900)


class ServiceStatus(BaseModel):
    queues: dict[str, int | None]  # messages waiting; None: the broker did not answer for it
    workers: dict[str, list[str]] | None  # live workers and their queues; None: not knowable (embedded broker)
    submissions_by_state: dict[str, int]
    case_runs_by_state: dict[str, dict[str, int]]  # backend -> state -> count
    failures_by_reason: dict[str, int]
    stuck_case_runs: int
    grades_completing: int = 0  # current grades stored whose lab check is not yet (worker.grading.complete_grade)
    lti_failing: int = 0  # assignments whose scores the LMS gradebook refused last (grader.services.lti.outbox)
    durations_s: list[float]  # wall time of every case measured (not reused), for the histogram
    broker_error: str | None = None
    # Each live worker's case slots, warm or warming (grader.core.warmth); None: the broker keeps no such record
    warmth: list[dict] | None = None
    last_warm_up_s: float | None = None  # how long the last finished warm-up took, start to every slot warm


def failure_reason(run: CaseRun) -> str:
    """A failed case run's reason, as a small fixed set an operator can alert on."""
    error = (run.error or "").lower()
    if error.startswith("memory limit exceeded"):  # worker.errors.MEMORY_LIMIT_EXCEEDED: the service's bound
        return "memory_limit"
    if run.result_status == "timeout" or "time limit" in error:
        return "timeout"
    if "provenance" in error:
        return "provenance"
    if "gave up after" in error:
        return "worker_lost"
    if run.result_status == "invalid":
        return "invalid_result"
    if "case process" in error or "exit" in error:
        return "case_crashed"
    return "other"


def service_status(session: Session, *, timeout_s: float = 1.0) -> ServiceStatus:
    broker_error = None
    try:
        queues, workers = dispatch.queue_depths(), dispatch.live_workers(timeout_s=timeout_s)
    except Exception as exc:  # noqa: BLE001 - the broker down is itself the thing to see
        queues, workers, broker_error = {}, {}, f"{type(exc).__name__}: {exc}"
    try:
        live, last_warm_up = warmth.live(), warmth.last_warm_up_s()
    except Exception as exc:  # noqa: BLE001 - as above: unknown, never "no worker"
        live, last_warm_up = None, None
        broker_error = broker_error or f"{type(exc).__name__}: {exc}"
    by_state: dict[str, dict[str, int]] = {}
    for backend, state, n in session.execute(
            select(CaseRun.backend, CaseRun.status, func.count()).group_by(CaseRun.backend, CaseRun.status)):
        by_state.setdefault(backend, {})[state] = n
    failed = session.scalars(select(CaseRun).where(CaseRun.status == CaseRunState.FAILED))
    now = utcnow()
    stuck = session.scalar(select(func.count()).select_from(CaseRun).where(
        lifecycle.lease_expired(now) | lifecycle.queue_lease_expired(now)))
    completing = session.scalar(select(func.count()).select_from(Grade).where(
        Grade.superseded_at.is_(None), Grade.completed_at.is_(None)))
    lti_failing = session.scalar(select(func.count()).select_from(LtiOutbox).where(LtiOutbox.last_error.is_not(None)))
    durations = session.scalars(select(CaseRun.wall_s).where(
        CaseRun.status == CaseRunState.DONE, CaseRun.reused_from_id.is_(None), CaseRun.wall_s.is_not(None))).all()
    return ServiceStatus(
        queues=queues, workers=workers, broker_error=broker_error,
        submissions_by_state=dict(session.execute(
            select(Submission.status, func.count()).group_by(Submission.status)).all()),
        case_runs_by_state=by_state, failures_by_reason=dict(Counter(failure_reason(r) for r in failed)),
        stuck_case_runs=stuck or 0, grades_completing=completing or 0, durations_s=[float(d) for d in durations],
        lti_failing=lti_failing or 0, last_warm_up_s=last_warm_up,
        warmth=None if live is None else [{"worker": w.name, "queues": list(w.queues), "slots": w.slots,
                                           "warm": w.warm, "consuming": w.consuming, "warm_s": w.warm_s,
                                           "warming_for_s": None if w.consuming else max(0.0, time.time() -
                                                                                          w.started_at)}
                                          for w in live])


def _ping(node: str, timeout_s: float) -> bool | None:
    """Whether the Celery worker named `node` answers a ping within timeout_s; None where the broker has no broadcast
    (the embedded one)."""
    # lazy: Celery loads only where a worker is asked (grader.main never loads it)
    from worker.celery_app import app

    if str(app.conf.broker_url).startswith("filesystem"):
        return None
    return any(node in reply for reply in app.control.ping(destination=[node], timeout=timeout_s) or [])


def worker_health(node: str, *, timeout_s: float = 10.0, now: float | None = None) -> tuple[bool, str]:
    """A worker's own health, its container's check (`grader worker --healthy`): it answers Celery's ping by its node
    name, and its warm gate's record in the broker (grader.core.warmth, renewed every RENEW_S) is live and says it
    takes cases, every case slot warm. A worker still warming up answers but is not healthy yet: it takes no case
    (worker.warm_gate). Returns whether it is healthy and one line saying what was seen, warm gate included."""
    try:
        answered = _ping(node, timeout_s)
        live = warmth.live()
    except Exception as exc:  # noqa: BLE001 - a broker that does not answer is itself the thing to say
        return False, f"unhealthy: the broker did not answer ({type(exc).__name__}: {exc})"
    if answered is False:
        return False, f"unhealthy: {node} did not answer a ping within {timeout_s:g} s"
    if live is None:  # a broker that keeps no records: the ping alone says
        return True, f"healthy: {node} answered (the broker keeps no warm-up records)"
    record = next((w for w in live if w.name == node), None)
    if record is None:
        return False, (f"unhealthy: {node} renewed no warm-up record within {warmth.RECORD_TTL_S:.0f} s (its warm gate "
                       "is not running)")
    if not record.consuming:
        since = (time.time() if now is None else now) - record.started_at
        return False, (f"unhealthy: {node} is warming up, {record.warm} of {record.slots} case slots warm after "
                       f"{since:.0f} s; it takes no case yet")
    return True, (f"healthy: {node} {'answered' if answered else 'renews its record'}; {record.warm} of "
                  f"{record.slots} case slots warm, taking cases (warmed up in {record.warm_s:.1f} s)")


class StatusCollector:
    """A prometheus_client collector reading service_status at each scrape."""

    def __init__(self, session_factory):
        self.session_factory = session_factory

    def collect(self):
        with self.session_factory() as session:
            status = service_status(session)
        depth = GaugeMetricFamily("grader_queue_depth", "Messages waiting in a Celery queue", labels=["queue"])
        for queue, n in status.queues.items():
            if n is not None:
                depth.add_metric([queue], n)
        yield depth
        up = GaugeMetricFamily("grader_broker_up", "1 when the broker answered this scrape")
        up.add_metric([], 0 if status.broker_error else 1)
        yield up
        if status.workers is not None:
            workers = GaugeMetricFamily("grader_worker_up", "A Celery worker answering remote control, per queue",
                                        labels=["worker", "queue"])
            for name, queues in status.workers.items():
                for queue in queues:
                    workers.add_metric([name, queue], 1)
            yield workers
        if status.warmth is not None:
            slots = GaugeMetricFamily("grader_worker_slots", "A live worker's case slots, warm or warming; it takes "
                                      "no case until every slot is warm", labels=["worker", "state"])
            consuming = GaugeMetricFamily("grader_worker_consuming_cases", "1 once a worker's slots are all warm and "
                                          "it consumes its case queues, 0 while it warms up", labels=["worker"])
            for w in status.warmth:
                slots.add_metric([w["worker"], "warm"], w["warm"])
                slots.add_metric([w["worker"], "warming"], w["slots"] - w["warm"])
                consuming.add_metric([w["worker"]], 1 if w["consuming"] else 0)
            yield slots
            yield consuming
        if status.last_warm_up_s is not None:
            last = GaugeMetricFamily("grader_last_warm_up_seconds", "How long the last worker took from its start to "
                                     "every case slot warm")
            last.add_metric([], status.last_warm_up_s)
            yield last
        submissions = GaugeMetricFamily("grader_submissions", "Submissions by state", labels=["state"])
        for state, n in status.submissions_by_state.items():
            submissions.add_metric([state], n)
        yield submissions
        runs = GaugeMetricFamily("grader_case_runs", "Case runs by backend and state", labels=["backend", "state"])
        for backend, states in status.case_runs_by_state.items():
            for state, n in states.items():
                runs.add_metric([backend, state], n)
        yield runs
        failures = GaugeMetricFamily("grader_case_run_failures", "Failed case runs by reason", labels=["reason"])
        for reason, n in status.failures_by_reason.items():
            failures.add_metric([reason], n)
        yield failures
        stuck = GaugeMetricFamily("grader_stuck_case_runs", "Case runs past their lease or queue lease")
        stuck.add_metric([], status.stuck_case_runs)
        yield stuck
        # Named grader_grades_drawing before issue 32 (when completing a grade drew PNGs); removed (docs/operator.md).
        completing = GaugeMetricFamily("grader_grades_completing", "Grades stored whose lab check is being evaluated "
                                                                   "(the score is final)")
        completing.add_metric([], status.grades_completing)
        yield completing
        lti = GaugeMetricFamily("grader_lti_sends_failing", "Assignments whose last send to an LMS gradebook failed")
        lti.add_metric([], status.lti_failing)
        yield lti
        buckets = [(str(b), sum(1 for d in status.durations_s if d <= b)) for b in DURATION_BUCKETS_S]
        buckets.append(("+Inf", len(status.durations_s)))
        yield HistogramMetricFamily("grader_case_run_duration_seconds", "Wall time of measured (not reused) case runs",
                                    buckets=buckets, sum_value=sum(status.durations_s))
