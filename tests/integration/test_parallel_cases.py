"""A worker with two case slots, on Redis and a database of its own, the API beside it: it takes no case until both
slots are warm, /metrics says so meanwhile, and then one submission's runs execute side by side on the two slots
with the grade stored once (worker.warm_gate, worker.celery_app.worker_concurrency).

One worker serves both tests (its warm-up is the slow part); the module's fixture submits the reference sheet right
after the worker says it is ready and watches what happens, and each test checks its own part of what was seen."""

from __future__ import annotations

import os
import re
import time
from dataclasses import dataclass, field

import httpx
import pytest
from sqlalchemy import func, select
from sqlalchemy.orm import Session

from tests import services
from tests.factories import create_people, reference_sheet
from tools.harness.processes import WARM_UP_LIMIT_S

pytestmark = [pytest.mark.integration, pytest.mark.slow]

SLOTS = 2


@dataclass
class Seen:
    """What the fixture saw: /metrics while warming and once consuming; each poll until graded."""

    submission_id: int
    engine: object
    metrics_warming: str
    metrics_warm: str = ""
    # (worker consuming per /metrics, cpu queue depth per /metrics, the runs' states) at each poll
    polls: list[tuple[bool, int | None, list[str]]] = field(default_factory=list)


def _gauge(text: str, name: str, **labels: str) -> float | None:
    for line in text.splitlines():
        match = re.fullmatch(rf"{name}\{{(.*)\}} (\S+)", line)
        if match and all(f'{k}="{v}"' in match.group(1) for k, v in labels.items()):
            return float(match.group(2))
    return None


@pytest.fixture(scope="module")
def seen(tmp_path_factory):
    from grader.client import Client
    from grader.core.db import make_engine, migrate
    from grader.core.models import CaseRun

    redis = services.redis_client()
    url = services.SPARE_REDIS_URL  # the session's stack keeps REDIS_URL; this worker must not take its runs
    spare = type(redis).from_url(url)
    spare.flushdb()
    folder = tmp_path_factory.mktemp("two-slots")
    database_url = f"sqlite:///{folder / 'grader.db'}"
    migrate(database_url)
    engine = make_engine(database_url)
    with Session(engine) as session:
        tokens = create_people(session, course="l03-test", other_course="other-course")
        session.commit()
    env = dict(os.environ, DATABASE_URL=database_url, BROKER_URL=url, DATA_DIR=str(folder),
               PYTHONPATH=str(services.ROOT), WORKER_CONCURRENCY=str(SLOTS), CASE_TIME_LIMIT_S="600",
               RATE_LIMIT_SUBMISSIONS="1000/minute")
    port = services.free_port()
    api = services.start_api(env, port, folder / "api.log")
    worker = services.start_worker(env, "cpu,grade", folder / "worker.log")
    try:
        base = f"http://127.0.0.1:{port}"

        def metrics() -> str:
            return httpx.get(f"{base}/metrics", timeout=30).text

        # The worker records itself on its consumer's first tick, just after it says it is ready.
        services.wait_for(lambda: _gauge(metrics(), "grader_worker_consuming_cases") is not None,
                          "the worker's warm-up record in /metrics", worker, folder / "worker.log")
        warming = metrics()
        client = Client(base, tokens["alice"])
        created = client.submit(reference_sheet())
        found = Seen(created["id"], engine, warming)
        deadline = time.monotonic() + WARM_UP_LIMIT_S + 600
        while True:
            text = metrics()
            with Session(engine) as session:
                states = list(session.scalars(select(CaseRun.status).where(
                    CaseRun.submission_id == created["id"]).order_by(CaseRun.id)))
            consuming = _gauge(text, "grader_worker_consuming_cases") == 1
            found.polls.append((consuming, _gauge(text, "grader_queue_depth", queue="cpu"), states))
            if consuming and not found.metrics_warm:
                found.metrics_warm = text
            if client.submission(created["id"])["status"] in ("graded", "failed"):
                break
            assert time.monotonic() < deadline, f"not graded: {found.polls[-1]}"
            assert worker.poll() is None, (folder / "worker.log").read_text()[-3000:]
            time.sleep(0.5)
        yield found
    finally:
        services.stop(worker)
        services.stop(api)
        engine.dispose()
        spare.flushdb()


def test_a_worker_takes_no_case_until_its_slots_are_warm_and_metrics_say_so(seen):
    warming = seen.metrics_warming
    assert _gauge(warming, "grader_worker_consuming_cases") == 0
    assert _gauge(warming, "grader_worker_slots", state="warming") == SLOTS
    assert _gauge(warming, "grader_worker_slots", state="warm") == 0
    cold = [poll for poll in seen.polls if not poll[0]]
    assert cold, "the worker was warm before the first look: nothing was seen while it warmed up"
    runs = len(cold[0][2])
    for _, depth, states in cold:  # while warming, every run stays queued and its message stays in the broker
        assert set(states) == {"queued"}, states
        assert depth == runs, (depth, runs)
    assert any(poll[0] for poll in seen.polls), "never seen consuming"
    warm = seen.metrics_warm
    assert _gauge(warm, "grader_worker_slots", state="warm") == SLOTS
    assert _gauge(warm, "grader_worker_slots", state="warming") == 0
    assert re.search(r"^grader_last_warm_up_seconds \d", warm, re.M), warm


def test_one_submissions_runs_execute_at_once_on_two_slots_and_it_is_graded_once(seen):
    from grader.core.models import CaseRun, Event, Grade

    with Session(seen.engine) as session:
        runs = session.scalars(select(CaseRun).where(CaseRun.submission_id == seen.submission_id)).all()
        grades = session.scalar(select(func.count()).select_from(Grade).where(
            Grade.submission_id == seen.submission_id))
        graded_events = session.scalar(select(func.count()).select_from(Event).where(
            Event.submission_id == seen.submission_id, Event.case_run_id.is_(None), Event.state == "graded"))
    assert all(r.status == "done" and r.started_at and r.finished_at for r in runs), [(r.name, r.status) for r in runs]
    assert len({r.worker_pid for r in runs}) == SLOTS  # both slots ran some
    overlapping = [(a.name, b.name) for a in runs for b in runs
                   if a.id < b.id and a.worker_pid != b.worker_pid
                   and a.started_at < b.finished_at and b.started_at < a.finished_at]
    assert overlapping, [(r.name, r.worker_pid, r.started_at, r.finished_at) for r in runs]
    assert grades == 1 and graded_events == 1
