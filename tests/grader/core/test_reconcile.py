"""Nothing is lost: a broker outage at submit time leaves durable queued runs that the reconciler re-sends."""

from __future__ import annotations

import os
import subprocess
from datetime import timedelta

from click.testing import CliRunner
from sqlalchemy import select, update

from tests.factories import heavy_imports, reference_sheet


def test_broker_down_at_submit_keeps_the_runs_and_the_reconciler_resends_them(api, monkeypatch):
    from grader import dispatch
    from grader.cli.service import reconcile
    from grader.core.db import new_session
    from grader.core.models import CaseRun, utcnow
    from grader.core.settings import settings

    def broker_down(*args):
        raise ConnectionError("broker unreachable")

    monkeypatch.setattr(dispatch, "send_case_run", broker_down)
    response = api.client.post("/v1/submissions", json={"sheet": reference_sheet()}, headers=api.as_("alice"))
    assert response.status_code == 202
    submission_id = response.json()["id"]
    runs = api.client.get(f"/v1/submissions/{submission_id}/case-runs", headers=api.as_("alice")).json()
    assert runs and all(r["status"] == "queued" and r["delivery"] == 1 for r in runs)

    # The broker is back; the fixture records every message sent from here on.
    monkeypatch.setattr(dispatch, "send_case_run", lambda *args, **options: api.sent.append((*args, options)))
    early = CliRunner().invoke(reconcile, [])
    assert early.exit_code == 0, early.output
    assert api.sent == [] and early.output == ""  # not yet past the queue lease: nothing is re-sent

    with new_session() as session:  # the queue lease passes without a worker ever seeing the messages
        session.execute(update(CaseRun).where(CaseRun.submission_id == submission_id)
                        .values(queued_at=utcnow() - timedelta(seconds=settings.queue_lease_s + 1)))
        session.commit()
    late = CliRunner().invoke(reconcile, [])
    assert late.exit_code == 0, late.output
    assert late.output.strip() == f"re-sent {len(runs)} case runs, 0 gradings"
    # Each case run sent exactly once, under its new delivery number, to the queue of its own backend.
    # Re-sent ahead of the runs queued since (behind any run whose worker died mid-case).
    assert sorted(api.sent) == sorted((r["id"], 2, r["backend"], {"priority": dispatch.REQUEUED_PRIORITY}) for r in runs)
    assert {r["backend"] for r in runs} == {"cpu"}
    after = api.client.get(f"/v1/submissions/{submission_id}/case-runs", headers=api.as_("alice")).json()
    assert all(r["status"] == "queued" and r["delivery"] == 2 for r in after)
    events = api.client.get(f"/v1/submissions/{submission_id}/events", headers=api.as_("alice")).json()
    assert [e["state"] for e in events].count("requeued") == len(runs)


def test_the_api_never_imports_genesis_or_torch():
    assert heavy_imports(["grader.main"], watch=("genesis", "torch", "celery")) == []


class _Clock:
    """Monotonic time that moves only when a pass works (`work_s` per liveness question) or the loop sleeps."""

    def __init__(self, work_s: float, passes: int):
        self.now, self.work_s, self.passes, self.sleeps = 100.0, work_s, passes, []

    def monotonic(self) -> float:
        return self.now

    def sleep(self, seconds: float) -> None:
        self.sleeps.append(round(seconds, 3))
        self.now += seconds
        if len(self.sleeps) == self.passes:
            raise KeyboardInterrupt  # ends `reconcile --every`


def _loop(api, monkeypatch, answers: list, *, broker_url: str, work_s: float) -> list[float]:
    from grader import dispatch
    from grader.cli import service
    from grader.core.settings import settings

    clock = _Clock(work_s, len(answers))

    def held_tasks():
        clock.now += clock.work_s  # asking the workers takes time; the interval counts it
        return answers.pop(0)

    monkeypatch.setattr(dispatch, "held_tasks", held_tasks)
    monkeypatch.setattr(dispatch, "broker_kept_marker", lambda: None)
    monkeypatch.setattr(service, "time", clock)
    monkeypatch.setattr(settings, "broker_url", broker_url)
    CliRunner().invoke(service.reconcile, ["--every", "15"])
    return clock.sleeps


def test_reconcile_every_is_measured_pass_start_to_pass_start(api, monkeypatch):
    # A pass that spends 4 s asking the workers sleeps 11 s: passes start 15 s apart, not 19 s.
    assert _loop(api, monkeypatch, [({}, {"cpu": 0})] * 3, broker_url="redis://127.0.0.1:1/0", work_s=4) == [11] * 3


def test_reconcile_asks_again_soon_while_the_broker_does_not_answer(api, monkeypatch):
    from grader.reconcile import UNKNOWN_RETRY_S

    # No answer (the broker restarting): the next pass comes UNKNOWN_RETRY_S after this one began, then the
    # interval is back once the broker answers.
    sleeps = _loop(api, monkeypatch, [None, None, ({}, {"cpu": 0})], broker_url="redis://127.0.0.1:1/0", work_s=1)
    assert sleeps == [UNKNOWN_RETRY_S - 1, UNKNOWN_RETRY_S - 1, 14]
    # The embedded broker never answers: its reconciler keeps the interval.
    assert _loop(api, monkeypatch, [None, None], broker_url="filesystem://", work_s=1) == [14, 14]


def test_a_lost_broker_resends_queued_runs_however_full_the_queue_and_pending_gradings(api):
    from grader.core.db import new_session
    from grader.core.lifecycle import HOST
    from grader.core.models import CaseRun, Submission, utcnow
    from grader.reconcile import find_and_requeue

    ids = [api.client.post("/v1/submissions", json={"sheet": reference_sheet()}, headers=api.as_("alice")).json()["id"]
           for _ in range(2)]
    with new_session() as session:
        session.execute(update(Submission).where(Submission.id == ids[1]).values(status="grading", grading_at=utcnow()))
        session.execute(update(CaseRun).where(CaseRun.submission_id == ids[1]).values(status="done"))
        session.commit()
        liveness = ({"cpu@host": set()}, {"cpu": 12, "grade": 0})  # a worker answers; new runs fill the queue again
        nothing = find_and_requeue(session=session, liveness=liveness)
        assert (nothing.case_runs, nothing.gradings) == ([], [])
        # One run was claimed a moment ago on this host by a process that is gone: no grace, and it goes first.
        gone = subprocess.Popen(["true"])
        gone.wait()
        killed = session.scalars(select(CaseRun).where(CaseRun.submission_id == ids[0])).first()
        killed.status, killed.worker, killed.worker_pid, killed.started_at = "running", HOST, gone.pid, utcnow()
        session.commit()
        resend = find_and_requeue(session=session, liveness=liveness, broker_lost=True)
        queued = session.scalars(select(CaseRun).where(CaseRun.submission_id == ids[0])).all()
        assert sorted(resend.case_runs) == sorted((r.id, 2, "cpu") for r in queued)  # young as they are
        assert all(r.status == "queued" and r.delivery == 2 for r in queued)
        assert resend.were_running == {killed.id}
        assert resend.gradings == [ids[1]]  # its grade task went with the broker


def test_the_reconciler_reports_a_lost_broker_only_for_a_marker_it_had_left_and_at_once(api, monkeypatch):
    from grader import dispatch, reconcile
    from grader.cli import service
    from grader.core.settings import settings

    broker = {"marker": False, "restarted": False}
    clock = _Clock(0, 20)
    passes = []

    def kept() -> bool:  # as dispatch.broker_kept_marker: a missing marker is left again
        was, broker["marker"] = broker["marker"], True
        return was

    def sleep(seconds: float) -> None:
        _Clock.sleep(clock, seconds)
        if clock.now >= 120 and not broker["restarted"]:  # Redis restarted without persistence at t=120
            broker.update(marker=False, restarted=True)

    monkeypatch.setattr(clock, "sleep", sleep)
    monkeypatch.setattr(dispatch, "held_tasks", lambda: ({}, {"cpu": 3}))
    monkeypatch.setattr(dispatch, "broker_kept_marker", kept)
    monkeypatch.setattr(reconcile, "find_and_requeue", lambda *, session, liveness, broker_lost, beating=None:
                        passes.append((clock.now, broker_lost)) or reconcile.Resend())
    monkeypatch.setattr(service, "time", clock)
    monkeypatch.setattr(settings, "broker_url", "redis://127.0.0.1:1/0")
    CliRunner().invoke(service.reconcile, ["--every", "15"])
    # The first pass only leaves the marker; the loss at t=120 is seen by the watch at t=121 and acted on at once,
    # then passes are 15 s apart again.
    assert passes == [(100, False), (115, False), (121, True), (136, False)]


def test_a_grade_task_no_live_worker_holds_is_resent_once_the_grade_queue_is_empty(api):
    """A worker killed while it held a grade task (prefetched behind a case) leaves the message in the broker's
    unacknowledged set until the visibility timeout (the lease, 17 min shipped): liveness re-sends it instead, once
    it is older than the grace, no answering worker holds it and the grade queue is empty; a held one, a young one or
    one that may still wait in a non-empty queue is left alone. The same holds for a graded sheet whose lab check is
    still to come."""
    from datetime import timedelta

    from grader.core.db import new_session
    from grader.core.models import CaseRun, Event, Grade, Submission, utcnow
    from grader.dispatch import grade_held
    from grader.reconcile import LIVENESS_GRACE_S, find_and_requeue

    ids = [api.client.post("/v1/submissions", json={"sheet": reference_sheet()}, headers=api.as_("alice")).json()["id"]
           for _ in range(2)]
    old = utcnow() - timedelta(seconds=LIVENESS_GRACE_S + 5)
    with new_session() as session:
        session.execute(update(CaseRun).where(CaseRun.submission_id.in_(ids)).values(status="done"))
        session.execute(update(Submission).where(Submission.id.in_(ids)).values(status="grading", grading_at=old))
        session.commit()
        held = {"cpu@host": {grade_held(ids[0]), grade_held(ids[1])}}
        assert find_and_requeue(session=session, liveness=(held, {"cpu": 0, "grade": 0})).gradings == []
        assert find_and_requeue(session=session, liveness=({"cpu@host": set()}, {"cpu": 0, "grade": 1})).gradings == []
        resend = find_and_requeue(session=session, liveness=({"cpu@host": {grade_held(ids[1])}}, {"cpu": 0, "grade": 0}))
        assert resend.gradings == [ids[0]]
        note = session.scalars(select(Event).where(Event.submission_id == ids[0]).order_by(Event.id.desc())).first()
        assert note.state == "grading" and "no live worker holds it" in note.detail, note.detail
        # ids[0] was re-sent just now, so it is young again: the next pass leaves it to the worker that takes it
        assert find_and_requeue(session=session, liveness=({"cpu@host": set()}, {"cpu": 0, "grade": 0})).gradings \
            == [ids[1]]
        # A graded sheet whose lab check never came: re-sent as a completing task by the same rule.
        session.execute(update(Submission).where(Submission.id == ids[1]).values(status="graded", grading_at=old))
        session.add(Grade(submission_id=ids[1], rubric_lesson="L03", rubric_version="2", rubric_hash="h", total=0,
                          max_total=30, report={}))
        session.commit()
        resend = find_and_requeue(session=session, liveness=({"cpu@host": set()}, {"cpu": 0, "grade": 0}))
        assert resend.gradings == [ids[1]]
        note = session.scalars(select(Event).where(Event.submission_id == ids[1]).order_by(Event.id.desc())).first()
        assert note.state == "completing" and "no live worker holds it" in note.detail, note.detail


def test_a_run_on_a_host_whose_worker_stopped_beating_is_requeued_without_waiting_for_its_lease(api, tmp_path,
                                                                                                  monkeypatch):
    """Issue 46: a worker container SIGKILLed mid-case answers nothing, and its process ids are in another PID
    namespace; its run waited for its lease (17 minutes). Every worker renews its record in the broker's warmth store
    every few seconds, busy or not: a host with no live record and no answering worker is dead."""
    import time as clock

    from grader.core import warmth
    from grader.core.db import new_session
    from grader.core.models import CaseRun, Event, utcnow
    from grader.core.settings import settings
    from grader.reconcile import LIVENESS_GRACE_S, beating_hosts, find_and_requeue

    sid = api.client.post("/v1/submissions", json={"sheet": reference_sheet()}, headers=api.as_("alice")).json()["id"]
    liveness = ({"cpu-grade@alive": set()}, {"cpu": 0, "grade": 0})  # another host's worker answers
    # The workers' records, in the embedded broker's store: the killed host's stopped RECORD_TTL_S + 1 s ago.
    monkeypatch.setattr(settings, "data_dir", tmp_path)
    monkeypatch.setattr(settings, "broker_url", "filesystem://")
    for name in ("cpu-grade@alive", "cpu-grade@killed"):
        warmth.record(warmth.WorkerWarmth(name=name, queues=("cpu",), slots=1, warm=1, started_at=clock.time(),
                                          warm_s=1.0))
    assert beating_hosts() == {"alive", "killed"}
    with new_session() as session:
        run = session.scalars(select(CaseRun).where(CaseRun.submission_id == sid)).first()
        run.status, run.worker, run.worker_pid = "running", "killed", 7
        run.started_at = utcnow() - timedelta(seconds=LIVENESS_GRACE_S + 5)
        session.commit()
        # Still beating (busy in a long case, too busy to answer): left alone.
        assert find_and_requeue(session=session, liveness=liveness, beating=beating_hosts()).case_runs == []
        record = tmp_path / "broker" / "warmth" / "cpu-grade@killed.json"
        stale = clock.time() - warmth.RECORD_TTL_S - 1
        os.utime(record, (stale, stale))
        assert beating_hosts() == {"alive"}
        # Without heartbeats known, the lease decides, as before.
        assert find_and_requeue(session=session, liveness=liveness, beating=None).case_runs == []
        resend = find_and_requeue(session=session, liveness=liveness, beating=beating_hosts())
        assert resend.case_runs == [(run.id, 2, "cpu")] and resend.were_running == {run.id}
        note = session.scalars(select(Event).where(Event.case_run_id == run.id).order_by(Event.id.desc())).first()
        assert note.state == "requeued" and "its worker stopped beating" in note.detail, note.detail


def test_the_reconciler_is_healthy_only_while_it_finishes_passes(api, tmp_path, monkeypatch):
    """Issue 46: the reconciler container inherited the API's health check (an HTTP server it does not run) and was
    never healthy. Its own: a pass finished within the limit."""
    import time as clock

    from grader.cli import service
    from grader.core.settings import settings
    from grader.reconcile import mark_pass

    monkeypatch.setattr(settings, "data_dir", tmp_path)
    never = CliRunner().invoke(service.reconcile, ["--healthy-within", "60"])
    assert never.exit_code == 1 and "unhealthy: the reconciler never finished a pass" in never.output, never.output
    monkeypatch.setattr(settings, "broker_url", "filesystem://")
    assert CliRunner().invoke(service.reconcile, []).exit_code == 0  # one pass
    healthy = CliRunner().invoke(service.reconcile, ["--healthy-within", "60"])
    assert healthy.exit_code == 0 and healthy.output.startswith("healthy: last pass"), healthy.output
    mark_pass(clock.time() - 90)
    late = CliRunner().invoke(service.reconcile, ["--healthy-within", "60"])
    assert late.exit_code == 1 and "last finished a pass 90 s ago" in late.output, late.output
