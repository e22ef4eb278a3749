"""The API as deployed: several processes (uvicorn --workers) over one PostgreSQL database and one Redis, the per-token
submission limit counted in Redis and so held across every process, and conditional reads answered by any of them.
Real uvicorn on loopback; no Celery worker (the submissions stay queued: the limit is what is measured)."""

from __future__ import annotations

import os
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import httpx
import pytest

from tests import services
from tests.factories import create_people, reference_sheet

LIMIT = 4
SENT = 16


def _cpu_ticks(pid: int) -> int:
    """utime + stime of one process, in clock ticks (/proc/PID/stat)."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return int(fields[11]) + int(fields[12])


def _api_processes(supervisor: int) -> list[int]:
    """uvicorn's worker processes (spawned by multiprocessing), not its resource tracker."""
    return [pid for pid in services.children(supervisor)
            if b"spawn_main" in Path(f"/proc/{pid}/cmdline").read_bytes()]


@pytest.fixture
def two_processes(tmp_path):
    from sqlalchemy.orm import Session

    from grader.core.db import make_engine, migrate

    redis = services.redis_client()
    redis.flushdb()
    with services.postgres_database() as database_url:
        migrate(database_url)
        engine = make_engine(database_url)
        with Session(engine) as session:
            tokens = create_people(session, course="l03-procs", other_course="other-procs")
            session.commit()
        engine.dispose()
        env = dict(os.environ, DATABASE_URL=database_url, BROKER_URL=services.REDIS_URL,
                   RATE_LIMIT_STORAGE_URL=services.REDIS_URL, DATA_DIR=str(tmp_path), PYTHONPATH=str(services.ROOT),
                   RATE_LIMIT_SUBMISSIONS=f"{LIMIT}/minute", STUDENT_WAITING_RUNS_MAX="1000", API_WORKERS="2")
        port = services.free_port()
        api = services.start_api(env, port, tmp_path / "api.log", workers=2)
        try:
            deadline = time.monotonic() + services.STARTUP_LIMIT_S
            while len(_api_processes(api.pid)) < 2 and time.monotonic() < deadline:
                time.sleep(0.2)
            yield f"http://127.0.0.1:{port}", tokens, api
        finally:
            services.stop(api)
            redis.flushdb()


def _submit(url: str, token: str) -> httpx.Response:
    # a connection of its own each time: the kernel hands it to whichever process is free to accept
    return httpx.post(f"{url}/v1/submissions", json={"sheet": reference_sheet()},
                      headers={"Authorization": f"Bearer {token}"}, timeout=60)


def test_the_per_token_limit_holds_across_two_api_processes_sharing_redis(two_processes):
    url, tokens, api = two_processes
    workers = _api_processes(api.pid)
    assert len(workers) == 2, f"uvicorn --workers 2 started {len(workers)} processes"
    before = {pid: _cpu_ticks(pid) for pid in workers}
    with ThreadPoolExecutor(SENT) as pool:
        answers = list(pool.map(lambda _: _submit(url, tokens["alice"]), range(SENT)))
    codes = sorted(a.status_code for a in answers)
    assert codes == [202] * LIMIT + [429] * (SENT - LIMIT), [a.text[:200] for a in answers if a.status_code
                                                             not in (202, 429)]
    refused = [a for a in answers if a.status_code == 429]
    assert all(int(a.headers["retry-after"]) >= 1 for a in refused)
    # both processes answered some of them (each spent CPU on the burst), and still only LIMIT got through
    spent = {pid: _cpu_ticks(pid) - ticks for pid, ticks in before.items()}
    assert all(t > 0 for t in spent.values()), spent
    # another token has its own count, in the same shared store
    assert _submit(url, tokens["bob"]).status_code == 202


def test_a_report_not_complete_carries_no_etag_from_either_process(two_processes):
    url, tokens, _ = two_processes
    headers = {"Authorization": f"Bearer {tokens['alice']}"}
    # Not complete (queued): no ETag from either process, so no poll is ever answered 304 while it changes.
    sid = _submit(url, tokens["alice"]).json()["id"]
    for _ in range(4):
        answer = httpx.get(f"{url}/v1/submissions/{sid}", headers=headers | {"If-None-Match": "*"})
        assert answer.status_code == 200 and "etag" not in answer.headers


def test_several_api_processes_with_limits_counted_in_memory_are_refused():
    from grader.core.settings import Settings

    with pytest.raises(ValueError, match="api_workers: more than one API process needs rate_limit_storage_url"):
        Settings(api_workers=2)
    assert Settings(api_workers=2, rate_limit_storage_url="redis://127.0.0.1:6379/1").api_workers == 2
