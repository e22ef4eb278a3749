"""One real stack per test session: PostgreSQL database, Redis db, a Celery worker process, the API on loopback."""

from __future__ import annotations

import copy
import os
import time
import warnings

import pytest

from tests import services
from tests.factories import create_people, reference_sheet
from tests.integration.helpers import CHROMIUM, SHOTS, backlog, submit_and_wait
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


STACKS: list[Stack] = []  # the session's stack once a module has asked for it


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
            STACKS.append(Stack("redis-pg", f"http://127.0.0.1:{port}", database_url, env, data_dir, tokens, engine,
                                worker, api, logs=logs))
            yield STACKS[-1]
        finally:
            STACKS.clear()
            services.stop(worker)
            services.stop(api)
            engine.dispose()
            redis.flushdb()


DRAIN_STALL_S = 90  # a backlog unchanged this long is not being worked on (a run a test left stuck on purpose)


@pytest.fixture(scope="module", autouse=True)
def stack_drained(request):
    """After each module, wait until the session's stack owes no work, and warn naming the module when it did.

    Modules share one stack per test process in a shuffled order, and a lab check waits behind every queued case run
    (worker.celery_app). A module that left runs behind (a pool still drawing past its K, submissions it did not wait
    for) made a later module's lab check wait for them: in CI of 2026-12-08, test_two_lessons gave up on a lab check
    after 900 s that passed alone in 159 s. Waiting here puts that time on the module that caused it, and the warning
    says which and what it left. A backlog that stops moving for DRAIN_STALL_S is left as it is (and warned about)."""
    yield
    if not STACKS:
        return
    started = last_change = time.monotonic()
    left = backlog(STACKS[-1].engine)
    while left and time.monotonic() - last_change < DRAIN_STALL_S:
        time.sleep(0.5)
        now = backlog(STACKS[-1].engine)
        if now != left:
            left, last_change = now, time.monotonic()
    waited = time.monotonic() - started
    if left or waited > 5:
        warnings.warn(f"{request.module.__name__} left work on the session's stack: "
                      f"{'still ' + repr(left) + ' after' if left else 'drained in'} {waited:.0f} s", stacklevel=1)


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
