"""Failure paths on the real stack: a worker process killed mid-case, the reconciler, and backends never substituted."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from datetime import timedelta

import pytest
from sqlalchemy.orm import Session

from grader.core.models import utcnow
from rubric import load_rubric
from tests import services
from tests.integration.helpers import case_runs, events, grades_of, wait_until
from tests.factories import reference_sheet

pytestmark = [pytest.mark.integration, pytest.mark.slow]


def test_worker_killed_mid_case_requeues_and_grades_once(stack):
    client = stack.client("eve")  # force_rerun is a staff power; eve teaches the other course, so l03's class is untouched
    created = client.submit(reference_sheet() | {"student": "eve"}, force_rerun=True)

    def running_with_evidence():
        for run in case_runs(stack, created["id"]):
            if run.status == "running" and run.worker_pid:
                if (stack.data_dir / "artifacts" / "case-runs" / str(run.id) / f"try-{run.tries}" / "spec.json").exists():
                    return run
        return None

    victim = wait_until(running_with_evidence, "a case run in the middle of its case")
    genesis_processes = services.children(victim.worker_pid)
    os.kill(victim.worker_pid, signal.SIGKILL)  # the pool process holding the case, not the whole worker
    for pid in genesis_processes:
        os.kill(pid, signal.SIGKILL)

    final = client.wait(created["id"], poll_s=0.5, timeout_s=900)
    assert final["status"] == "graded", final
    after = {run.id: run for run in case_runs(stack, created["id"])}[victim.id]
    assert after.status == "done" and after.tries == 2 and after.delivery == victim.delivery
    assert after.reused_from_id is None  # force_rerun: measured again, not borrowed
    states = [e.state for e in events(stack, created["id"]) if e.case_run_id == victim.id]
    assert states.count("running") == 2 and states[-1] == "done"
    assert [e.state for e in events(stack, created["id"])].count("graded") == 1
    assert grades_of(stack, created["id"]) == 1


def test_reconciler_resends_runs_whose_worker_vanished(stack):
    """Case runs left 'running' past their lease (a worker machine lost, its messages gone) are re-queued and finish."""
    from grader.services.submissions import sheets, submit as submissions
    from grader.core.models import User

    with Session(stack.engine) as session:
        alice = session.query(User).filter_by(name="alice").one()
        sheet = reference_sheet()
        submission = submissions.create_submission(session=session, student=alice, lesson="L03", sheet=sheet,
                                            specs=sheets.cases_to_run(sheets.parse_sheet(sheet), load_rubric("L03")), force_rerun=False)
        session.flush()
        for run in submission.case_runs:  # claimed by a host that died; never on the broker any more
            run.status, run.worker, run.worker_pid = "running", "lost-host", 1
            run.lease_until = utcnow() - timedelta(hours=1)
        session.commit()
        submission_id = submission.id
    done = subprocess.run([sys.executable, "-c", "from grader.cli.service import reconcile; reconcile()"],
                          env=stack.env, cwd=services.ROOT, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert done.stdout.startswith("re-sent"), done.stdout
    final = stack.client("alice").wait(submission_id, poll_s=0.5, timeout_s=900)
    assert final["status"] == "graded"
    for run in case_runs(stack, submission_id):
        assert run.status == "done" and run.delivery == 2 and run.worker != "lost-host"
    assert "requeued" in [e.state for e in events(stack, submission_id)]
    assert grades_of(stack, submission_id) == 1


def test_rocm_is_refused_until_a_worker_listens_then_fails_on_one_without_rocm_never_on_cpu(stack):
    """A backend is a staff power, and a request for one no worker listens on would wait forever: refused at once.
    Once a worker listens on rocm but has no ROCm device (this machine), each case fails with the provenance error."""
    with pytest.raises(RuntimeError, match=r"(?s)HTTP 403.*only staff choose the backend"):
        stack.client("alice").submit(reference_sheet(), backend="rocm")
    client = stack.client("eve")  # staff of the other course, so l03's class is untouched
    sheet = reference_sheet() | {"student": "eve"}
    with pytest.raises(RuntimeError, match=r"(?s)HTTP 409.*no worker is listening on queue 'rocm'"):
        client.submit(sheet, backend="rocm")
    redis = services.redis_client()
    assert sum(redis.llen(key) for key in redis.scan_iter("rocm*")) == 0  # nothing left waiting on the rocm queue
    # Started as the ROCm worker is deployed (docker-compose.yml: WARM_UP_BACKEND=rocm), its slot warms up on rocm:
    # without a ROCm device that warm-up fails in seconds and the worker listens, rather than first building every
    # scene of the lesson on the cpu it never serves (56 s idle, 90-150 s on a loaded machine, of this test's 200 s).
    rocm = services.start_worker(stack.env | {"WARM_UP_BACKEND": "rocm"}, "rocm", stack.logs / "worker-rocm.log")
    try:
        deadline, created = time.monotonic() + 180, None
        while created is None:  # refused until the new worker answers the broker's roll call
            try:
                created = client.submit(sheet, backend="rocm")
            except RuntimeError as exc:
                if "HTTP 409" not in str(exc) or time.monotonic() > deadline:
                    raise
                time.sleep(2)
        total = created["progress"]["total"]
        final = client.wait(created["id"], poll_s=0.5, timeout_s=900)
    finally:
        services.stop(rocm)
    assert final["progress"]["failed"] == total
    for run in client.case_runs(created["id"]):
        assert run["backend"] == "rocm" and run["status"] == "failed"
        assert run["actual_backend"] in (None, "rocm") and "provenance error" in run["error"], run["error"]
        assert run["tries"] == 1  # a case failure is a result, never retried or moved to another backend
    # A failed case is a result, so the submission is graded on what it holds: every item decided by a measurement
    # is "not measured" (naming the rocm failure), every other item is decided from the answers alone.
    assert final["status"] == "graded", final
    assert grades_of(stack, created["id"]) == 1
    rubric = load_rubric("L03")
    kinds = {item.id: item.kind for item in rubric.items}
    grade = client.grade(created["id"])
    assert [i["id"] for i in grade["items"]] == list(kinds)
    for item in grade["items"]:
        if kinds[item["id"]] == "measured":
            assert (item["verdict"], item["score"]) == ("not_measured", 0), item
        else:
            assert item["verdict"] == "credit", item  # the reference answers, decided without a run
    assert any("failed on rocm: provenance error" in i["feedback"] for i in grade["items"])
    assert grade["total"] == sum(item.points for item in rubric.items if item.kind != "measured") < grade["max_total"]


def test_a_whole_worker_killed_mid_case_is_noticed_by_liveness_not_its_lease(stack):
    """SIGKILL of a whole Celery worker (main process and case processes) mid-case, with the shipped reconciler
    interval and the stack's 600 s case limit (lease 720 s): the run is re-queued within seconds because no live
    worker holds it, and the submission is graded once."""
    from grader.reconcile import LIVENESS_GRACE_S, RECONCILE_EVERY_S

    # warm: a worker takes no case until its slots are warm (worker.warm_gate), and a cold one would see the stack's
    # warm worker take every run first
    victim_worker = services.start_worker(stack.env, "cpu", stack.logs / "worker-victim.log", warm=True)
    reconciler = subprocess.Popen([sys.executable, "-m", "grader.cli", "reconcile", "--every", str(RECONCILE_EVERY_S)],
                                  cwd=services.ROOT, env=stack.env, stdout=(stack.logs / "reconciler.log").open("ab"),
                                  stderr=subprocess.STDOUT, start_new_session=True)
    try:
        client = stack.client("eve")  # a staff power (see the first test)
        created = client.submit(reference_sheet() | {"student": "eve"}, force_rerun=True)

        def running_on_victim():
            pids = set(services.children(victim_worker.pid))
            for run in case_runs(stack, created["id"]):
                if run.status == "running" and run.worker_pid in pids:
                    return run
            return None

        victim = wait_until(running_on_victim, "a case run held by the victim worker")
        doomed = [victim_worker.pid, *services.children(victim_worker.pid)]
        doomed += [grandchild for pid in doomed[1:] for grandchild in services.children(pid)]
        for pid in doomed:
            os.kill(pid, signal.SIGKILL)
        killed_at = utcnow()

        def requeued():
            return next((e for e in events(stack, created["id"])
                         if e.case_run_id == victim.id and e.state == "requeued"), None)

        event = wait_until(requeued, "the killed worker's run re-queued", limit_s=120)
        noticed_s = (event.at - killed_at).total_seconds()
        print(f"\nre-queued {noticed_s:.1f} s after the SIGKILL: {event.detail}")
        assert "no live worker holds it" in event.detail or "is gone" in event.detail, event.detail
        assert noticed_s <= LIVENESS_GRACE_S + RECONCILE_EVERY_S + 5, f"noticed only after {noticed_s:.1f} s"
        final = client.wait(created["id"], poll_s=0.5, timeout_s=900)
        assert final["status"] == "graded", final
        after = {run.id: run for run in case_runs(stack, created["id"])}
        assert after[victim.id].status == "done" and after[victim.id].delivery == victim.delivery + 1
        assert all(run.status == "done" for run in after.values())
        assert grades_of(stack, created["id"]) == 1
    finally:
        for proc in (reconciler, victim_worker):
            services.stop(proc)


def test_messages_lost_with_the_broker_are_noticed_at_once(stack):
    """The cpu queue emptied under queued runs (what a Redis restart without persistence does to them): with the
    shipped reconciler interval, they are re-sent within seconds, not after the 1800 s queue lease."""
    from grader.reconcile import LIVENESS_GRACE_S, RECONCILE_EVERY_S

    reconciler = subprocess.Popen([sys.executable, "-m", "grader.cli", "reconcile", "--every", str(RECONCILE_EVERY_S)],
                                  cwd=services.ROOT, env=stack.env, stdout=(stack.logs / "reconciler.log").open("ab"),
                                  stderr=subprocess.STDOUT, start_new_session=True)
    try:
        client = stack.client("eve")  # a staff power (see the first test)
        created = client.submit(reference_sheet() | {"student": "eve"}, force_rerun=True)
        wait_until(lambda: any(r.status == "running" for r in case_runs(stack, created["id"])), "a run started")
        purge = "from worker.celery_app import app; print(app.connection_for_write().default_channel.queue_purge('cpu'))"
        purged = subprocess.run([sys.executable, "-c", purge], env=stack.env, cwd=services.ROOT, capture_output=True,
                                text=True, check=True, timeout=60)
        lost_at = utcnow()
        assert int(purged.stdout.strip() or 0) >= 1, "nothing was queued to lose"
        lost = {r.id for r in case_runs(stack, created["id"]) if r.status == "queued"}

        def resent():
            return [e for e in events(stack, created["id"]) if e.case_run_id in lost and e.state == "requeued"]

        found = wait_until(lambda: len(resent()) >= 1, "a lost message re-sent", limit_s=120) and resent()
        first_s = (min(e.at for e in found) - lost_at).total_seconds()
        print(f"\n{len(lost)} queued runs lost with the queue; first re-sent after {first_s:.1f} s: {found[0].detail}")
        assert "its message is gone" in found[0].detail
        assert first_s <= LIVENESS_GRACE_S + RECONCILE_EVERY_S + 5
        final = client.wait(created["id"], poll_s=0.5, timeout_s=900)
        assert final["status"] == "graded", final
        assert all(run.status == "done" for run in case_runs(stack, created["id"]))
        assert grades_of(stack, created["id"]) == 1
    finally:
        services.stop(reconciler)
