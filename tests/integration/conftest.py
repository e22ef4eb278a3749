"""One real stack per test session: PostgreSQL database, Redis db, a Celery worker process, the API on loopback."""

from __future__ import annotations

import copy
import os

import pytest

from tests import services
from tests.factories import create_people, reference_sheet
from tests.integration.helpers import CHROMIUM, SHOTS, submit_and_wait
from tools.harness.stack import Stack


@pytest.fixture(scope="session")
def kernel_cache_filled(measured) -> None:
    """The machine's Genesis kernel cache holds the lesson's kernels before a test copies it for processes it may
    SIGKILL (services.private_kernel_cache): on a fresh machine an empty copy would make every fresh worker compile
    for ~100 s, and a recovery timed from a worker being ready would time the compiler. `measured` compiles them
    (once per session, shared with every other user of it).

    The cache also holds worker.kernel_cache's marker, which says the kernels are there: without it, the first worker
    of every copy (the stack's, test_faults_under_load's, test_embedded's, a second host's) ran the compile's child
    process, every scene of the lesson once more (33 s idle, 90 s loaded, while the worker's slot waited on it), and
    a worker started beside it waited too. `compile_once` leaves it, once per machine: the worker's own code, under
    its file lock (so two test processes make one), and a no-op once the marker is there."""
    from worker.kernel_cache import compile_once

    compile_once("cpu")


@pytest.fixture(scope="session")
def stack(tmp_path_factory, kernel_cache_filled):
    from grader.core.db import make_engine, migrate

    redis = services.redis_client()
    redis.flushdb()
    data_dir = tmp_path_factory.mktemp("service")
    logs = data_dir / "logs"
    logs.mkdir()
    with services.postgres_database() as database_url:
        migrate(database_url)
        engine = make_engine(database_url)
        from sqlalchemy.orm import Session

        with Session(engine) as session:
            tokens = create_people(session, course="l03-test", other_course="other-course")
            session.commit()
        env = dict(os.environ, DATABASE_URL=database_url, BROKER_URL=services.REDIS_URL, DATA_DIR=str(data_dir),
                   CASE_TIME_LIMIT_S="600", PYTHONPATH=str(services.ROOT),
                   # One session submits as alice far more often than a student would; the limit and the cap on a
                   # student's waiting runs have their own tests (test_hostile_input, test_fair_queues).
                   RATE_LIMIT_SUBMISSIONS="1000/minute", STUDENT_WAITING_RUNS_MAX="1000",
                   # The LMS of test_lti_platform serves on loopback over plain http (grader.core.outbound).
                   OUTBOUND_ALLOW_HTTP="true", OUTBOUND_ALLOWED_HOSTS="127.0.0.1")
        env |= services.private_kernel_cache(data_dir)  # test_recovery SIGKILLs this stack's case processes
        port = services.free_port()
        api = services.start_api(env, port, logs / "api.log")
        worker = services.start_worker(env, "cpu,grade", logs / "worker-cpu.log")
        try:
            yield Stack("redis-pg", f"http://127.0.0.1:{port}", database_url, env, data_dir, tokens, engine, worker, api,
                        logs=logs)
        finally:
            services.stop(worker)
            services.stop(api)
            engine.dispose()
            redis.flushdb()


@pytest.fixture(scope="session")
def browser():
    """Debian's chromium driven by Playwright (its own browser download is unreachable from these machines)."""
    from playwright.sync_api import sync_playwright

    if not CHROMIUM.exists():
        pytest.fail(f"{CHROMIUM} is missing: `make .venv/.installed` installs Debian's chromium")
    SHOTS.mkdir(parents=True, exist_ok=True)
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=str(CHROMIUM), headless=True, args=["--no-sandbox"])
        yield browser
        browser.close()


@pytest.fixture(scope="session")
def graded(stack):
    """A small class graded for real, shared by the browser tests: Alice's reference sheet twice, Bob's with one
    wrong prediction (H3: the high lane goes farther)."""
    _, first = submit_and_wait(stack, reference_sheet(), who="alice")
    wrong = copy.deepcopy(reference_sheet()) | {"student": "bob"}
    wrong["answers"]["H3"]["high"] = "farther"
    _, bob = submit_and_wait(stack, wrong, who="bob")
    _, alice = submit_and_wait(stack, reference_sheet(), who="alice")
    assert first["status"] == alice["status"] == bob["status"] == "graded", (first, alice, bob)
    return {"alice": alice, "bob": bob, "alice_first": first}
