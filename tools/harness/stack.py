"""A whole service stack as real processes on loopback: the API and one CPU Celery worker (or several, on Redis +
PostgreSQL), over the embedded default (SQLite + filesystem broker) or Redis + PostgreSQL, with a course of students
and their tokens. The one harness the
benchmark (tools.bench) and the integration tests (tests/integration/conftest.py's `stack`) both start."""

from __future__ import annotations

import contextlib
import os
import uuid
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import redis
from sqlalchemy import create_engine, text
from sqlalchemy.orm import Session

from grader.client import Client
from grader.core.db import make_engine, migrate
from grader.services.identity import accounts

from tools.harness.processes import WARM_UP_LIMIT_S, ROOT, free_port, start_api, start_worker, stop, wait_for

KINDS = ("embedded", "redis-pg")
PG_ADMIN_URL = os.environ.get("BENCH_POSTGRES_URL", "postgresql+psycopg2://postgres@127.0.0.1:5432/test")
REDIS_URL = os.environ.get("BENCH_REDIS_URL", "redis://127.0.0.1:6379/14")
COURSE = "bench"


class ServiceUnavailable(RuntimeError):
    """PostgreSQL or Redis could not be reached."""


@contextlib.contextmanager
def postgres_database(admin_url: str | None = None, *, prefix: str = "grader_bench") -> Iterator[str]:
    """A uniquely named database on admin_url's server (default PG_ADMIN_URL), dropped afterwards; yields its URL."""
    admin_url = admin_url or PG_ADMIN_URL
    name = f"{prefix}_{uuid.uuid4().hex[:12]}"
    admin = create_engine(admin_url, isolation_level="AUTOCOMMIT")
    try:
        with admin.connect() as conn:
            conn.execute(text(f'CREATE DATABASE "{name}"'))
    except Exception as exc:
        admin.dispose()
        raise ServiceUnavailable(f"PostgreSQL at {admin_url.split('@')[-1]}: {exc}") from exc
    try:
        yield admin_url.rsplit("/", 1)[0] + f"/{name}"
    finally:
        with admin.connect() as conn:
            conn.execute(text(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)'))
        admin.dispose()


@contextlib.contextmanager
def redis_db(url: str | None = None) -> Iterator[str]:
    """The Redis db at url (default REDIS_URL), flushed before and after (the benchmark owns it while it runs)."""
    url = url or REDIS_URL
    client = redis.Redis.from_url(url)
    try:
        client.ping()
    except Exception as exc:
        raise ServiceUnavailable(f"Redis at {url}: {exc}") from exc
    client.flushdb()
    try:
        yield url
    finally:
        client.flushdb()
        client.close()


@dataclass
class Stack:
    """A started stack: where it answers, its database and environment, the people's tokens, its processes."""

    kind: str
    url: str
    database_url: str
    env: dict
    data_dir: Path
    tokens: dict[str, str]
    engine: object
    worker: object
    api: object
    students: list[str] = field(default_factory=list)
    logs: Path | None = None  # where the processes' logs are, when not in data_dir
    workers: list = field(default_factory=list)  # every CPU worker process, `worker` first

    def __post_init__(self):
        self.workers = self.workers or [self.worker]

    def worker_log(self, index: int) -> Path:
        """The log of the index-th worker (0: `worker`)."""
        return (self.logs or self.data_dir) / worker_log_name(index)

    def client(self, who: str = "alice", *, timeout: float = 120):
        return Client(self.url, self.tokens[who], timeout=timeout)


def _people(engine, students: int) -> tuple[dict[str, str], list[str]]:
    names = [f"s{i:03d}" for i in range(students)]
    with Session(engine) as session:
        course = accounts.get_or_create_course(session=session, name=COURSE)
        tokens = {name: accounts.create_token(session=session, user=accounts.get_or_create_user(
            session=session, course=course, name=name, role="student")) for name in names}
        tokens["prof"] = accounts.create_token(session=session, user=accounts.get_or_create_user(
            session=session, course=course, name="prof", role="instructor"))
        session.commit()
    return tokens, names


def worker_log_name(index: int) -> str:
    """worker.log for the first worker (as ever), worker-2.log, worker-3.log... for the others."""
    return "worker.log" if index == 0 else f"worker-{index + 1}.log"


@contextlib.contextmanager
def service_stack(kind: str, folder: Path, *, students: int = 1, worker_env: dict | None = None,
                  warm: bool = False, workers: int = 1, redis_url: str | None = None,
                  postgres_url: str | None = None) -> Iterator[Stack]:
    """Start the API and `workers` CPU workers (`cpu,grade` queues, separate Celery worker processes, each with its
    own case slots) over `kind`'s database and broker; stop them after. Several workers need a shared broker:
    redis-pg only (the embedded default is one worker on a filesystem broker, without heartbeats).
    `worker_env` adds to the environment of all (WORKER_CONCURRENCY=1: the slots of each worker); `warm`: yielded
    once every worker's case slots are warm (worker.warm_gate), not as soon as it is ready. `redis_url` and
    `postgres_url` (the server's admin URL) replace BENCH_REDIS_URL and BENCH_POSTGRES_URL (a test's own)."""
    if kind not in KINDS:
        raise ValueError(f"unknown stack {kind!r}; one of {', '.join(KINDS)}")
    if workers < 1 or (kind == "embedded" and workers > 1):
        raise ValueError(f"{workers} workers on {kind}: the embedded stack runs one worker, redis-pg one or more")
    data_dir = (folder / f"{kind}-{uuid.uuid4().hex[:6]}").absolute()
    data_dir.mkdir(parents=True)
    with contextlib.ExitStack() as cleanup:
        if kind == "embedded":
            database_url, broker_url = f"sqlite:///{data_dir / 'grader.db'}", ""  # "" derives the filesystem broker
        else:
            database_url = cleanup.enter_context(postgres_database(postgres_url))
            broker_url = cleanup.enter_context(redis_db(redis_url))
        migrate(database_url)
        engine = make_engine(database_url)
        cleanup.callback(engine.dispose)
        tokens, names = _people(engine, students)
        env = dict(os.environ, DATABASE_URL=database_url, BROKER_URL=broker_url, DATA_DIR=str(data_dir),
                   ARTIFACTS_DIR=str(data_dir / "artifacts"), PYTHONPATH=str(ROOT),
                   # The benchmark submits far faster than a student may; the limit is not what it measures.
                   RATE_LIMIT_SUBMISSIONS="100000/minute", STUDENT_WAITING_RUNS_MAX="100000",
                   # Its concurrent clients all come from 127.0.0.1, which the per-client cap would count as one.
                   CLIENT_MAX_IN_FLIGHT="10000") | (worker_env or {})
        port = free_port()
        api = start_api(env, port, data_dir / "api.log")
        cleanup.callback(stop, api)
        started = []
        # Each is started (up to Celery's "ready") before the next; with `warm`, all warm up side by side and are
        # waited for after: no worker's warm-up waits for another's.
        for index in range(workers):
            started.append(start_worker(env, "cpu,grade", data_dir / worker_log_name(index)))
            cleanup.callback(stop, started[-1])
        if warm:
            from worker.warm_gate import OPENED  # lazy, as in start_worker

            for index, proc in enumerate(started):
                wait_for(lambda i=index: OPENED in (data_dir / worker_log_name(i)).read_text(errors="replace"),
                         "celery worker's warm-up", proc, data_dir / worker_log_name(index), limit_s=WARM_UP_LIMIT_S)
        yield Stack(kind, f"http://127.0.0.1:{port}", database_url, env, data_dir, tokens, engine, started[0], api,
                    names, workers=started)
