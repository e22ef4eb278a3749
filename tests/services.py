"""Real services for integration tests: a fresh PostgreSQL database, a Redis db, a Celery worker, the API on loopback.

The process helpers live in tools.harness (the benchmark starts the same stack from there) and are re-exported here.
Outside CI a missing Redis/PostgreSQL skips the test; with CI=true it fails, so CI can never go green on skips.
"""

from __future__ import annotations

import contextlib
import os
import shutil
from pathlib import Path

import pytest

from tests.factories import ROOT
from tools.harness.processes import STARTUP_LIMIT_S, children, free_port, start_api, start_worker, stop, wait_for
from tools.harness.stack import ServiceUnavailable
from tools.harness.stack import postgres_database as _postgres_database

__all__ = ["PG_ADMIN_URL", "REDIS_URL", "ROOT", "SPARE_REDIS_URL", "STARTUP_LIMIT_S", "children", "free_port",
           "postgres_database", "private_kernel_cache", "redis_client", "start_api", "start_worker", "stop",
           "unavailable", "wait_for"]

PG_ADMIN_URL = os.environ.get("TEST_POSTGRES_URL", "postgresql+psycopg2://postgres@127.0.0.1:5432/test")


def _worker_index() -> int:
    """This test process's index under pytest-xdist (gw0 -> 0, gw1 -> 1, ...); 0 without xdist."""
    name = os.environ.get("PYTEST_XDIST_WORKER", "gw0")
    return int(name[2:]) if name[2:].isdigit() else 0


# Two Redis databases per test process, so that processes running side by side (pytest-xdist) never flush or read
# each other's broker. TEST_REDIS_URL names gw0's first one (default 11, the suite's number before xdist: gw0 has 11
# and 12, gw1 9 and 10, gw2 7 and 8, gw3 5 and 6; 13-15 stay for the benchmark, tools.harness.stack uses 14). A second
# test run on the same machine takes other numbers: TEST_REDIS_URL=redis://127.0.0.1:6379/4 uses 4, 5 and 2, 3.
_BASE_URL = os.environ.get("TEST_REDIS_URL", "redis://127.0.0.1:6379/11")
REDIS_DB = int(_BASE_URL.rsplit("/", 1)[1]) - 2 * _worker_index()
if REDIS_DB < 0:
    raise RuntimeError(f"TEST_REDIS_URL={_BASE_URL} leaves no Redis database pair for test process "
                       f"{os.environ.get('PYTEST_XDIST_WORKER')} (tests/services.py)")
REDIS_URL = f"{_BASE_URL.rsplit('/', 1)[0]}/{REDIS_DB}"
# The second database: a test that needs a broker of its own beside the session's stack (test_fair_broker).
SPARE_REDIS_URL = REDIS_URL.rsplit("/", 1)[0] + f"/{int(REDIS_URL.rsplit('/', 1)[1]) + 1}"


def private_kernel_cache(folder: Path) -> dict[str, str]:
    """Environment for Genesis processes a test may SIGKILL: a copy of the machine's kernel cache.

    quadrants (Genesis' kernel compiler) guards its cache with a lock file. A process killed while holding it leaves
    the file behind, and from then on every Genesis process on the machine compiles its kernels anew (~100 s each,
    far more on a loaded machine) until someone deletes it: seen here after a SIGKILL mid-case, when a whole test
    suite slowed to a crawl. Killed processes get their own copy, so the machine's cache is never left locked."""
    source = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "quadrants" / "qdcache"
    target = folder / "qdcache"
    if source.is_dir():
        shutil.copytree(source, target, ignore=shutil.ignore_patterns("*.lock"))
    return {"QD_OFFLINE_CACHE_FILE_PATH": str(target)}


def unavailable(what: str, exc: Exception):
    message = f"{what} is not reachable: {exc}"
    if os.environ.get("CI", "").lower() in ("1", "true", "yes"):
        pytest.fail(f"{message} (CI=true: integration services are required)")
    pytest.skip(message)


@contextlib.contextmanager
def postgres_database():
    """A uniquely named database on the test server, dropped afterwards; yields its URL."""
    with contextlib.ExitStack() as cleanup:
        try:
            url = cleanup.enter_context(_postgres_database(PG_ADMIN_URL, prefix="grader_test"))
        except ServiceUnavailable as exc:
            unavailable("PostgreSQL", exc)
        yield url


def redis_client():
    import redis

    client = redis.Redis.from_url(REDIS_URL)
    try:
        client.ping()
    except Exception as exc:
        unavailable("Redis", exc)
    return client
