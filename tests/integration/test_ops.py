"""What an operator watches, on the real stack: /metrics (Prometheus text format) and `grader status` against the
real Redis broker, the live Celery worker and PostgreSQL."""

from __future__ import annotations

import subprocess
import sys

import httpx
import pytest
from prometheus_client.parser import text_string_to_metric_families
from sqlalchemy import func, select
from sqlalchemy.orm import Session

from grader.core.models import CaseRun, Grade

pytestmark = [pytest.mark.integration, pytest.mark.slow]


def _samples(stack) -> dict[tuple[str, tuple], float]:
    response = httpx.get(f"{stack.url}/metrics", timeout=30)
    assert response.status_code == 200 and response.headers["content-type"].startswith("text/plain")
    return {(s.name, tuple(sorted(s.labels.items()))): s.value
            for family in text_string_to_metric_families(response.text) for s in family.samples}


def test_metrics_and_status_show_queues_workers_and_case_runs(stack, graded):
    # A message no worker consumes: the rocm queue's depth must count it.
    with_env = dict(stack.env)
    before = _samples(stack)
    assert before[("grader_broker_up", ())] == 1
    assert before[("grader_queue_depth", (("queue", "rocm"),))] == 0
    subprocess.run([sys.executable, "-c", "from grader import dispatch; dispatch.send_case_run(2**31 - 1, 1, 'rocm')"],
                   env=with_env, check=True, timeout=60)
    samples = _samples(stack)
    assert samples[("grader_queue_depth", (("queue", "rocm"),))] == 1
    workers = {dict(labels)["queue"] for (name, labels) in samples if name == "grader_worker_up"}
    assert {"cpu", "grade"} <= workers and "rocm" not in workers
    with Session(stack.engine) as session:
        done_on_cpu = session.scalar(select(func.count()).select_from(CaseRun).where(
            CaseRun.backend == "cpu", CaseRun.status == "done"))
        measured = session.scalar(select(func.count()).select_from(CaseRun).where(
            CaseRun.status == "done", CaseRun.reused_from_id.is_(None)))
        completing = session.scalar(select(func.count()).select_from(Grade).where(
            Grade.superseded_at.is_(None), Grade.completed_at.is_(None)))
    assert samples[("grader_case_runs", (("backend", "cpu"), ("state", "done")))] == done_on_cpu
    assert samples[("grader_case_run_duration_seconds_count", ())] == measured > 0
    assert samples[("grader_grades_completing", ())] == completing
    assert not any(name == "grader_grades_drawing" for name, _ in samples), "the old name is removed"

    printed = subprocess.run([sys.executable, "-m", "grader.cli", "status"], env=with_env, capture_output=True,
                             text=True, timeout=120)
    assert printed.returncode == 0, printed.stderr
    assert "rocm 1" in printed.stdout and "1 live" in printed.stdout and "cpu, grade" in printed.stdout, printed.stdout
    assert f"done {done_on_cpu}" in printed.stdout
    assert f"completing: {completing} grades stored" in printed.stdout
    dispatch_purge = "from worker.celery_app import app; app.connection_for_write().default_channel.queue_purge('rocm')"
    subprocess.run([sys.executable, "-c", dispatch_purge], env=with_env, check=True, timeout=60)
    assert _samples(stack)[("grader_queue_depth", (("queue", "rocm"),))] == 0
