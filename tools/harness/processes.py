"""Real service processes on loopback: a free port, the API (uvicorn), a Celery worker, waiting for them, stopping
them. Shared by the benchmark and the integration tests (tests/services.py re-exports these)."""

from __future__ import annotations

import contextlib
import os
import signal
import socket
import subprocess
import sys
import time
import uuid
from collections.abc import Callable
from pathlib import Path

import httpx

ROOT = Path(__file__).resolve().parent.parent.parent
# Safety stop for waits on real processes; never a claim about speed.
STARTUP_LIMIT_S = 120
# The same for a worker's warm-up (every case slot's Genesis process loading its kernels and building the lesson's
# scenes, all at once): ~20 s on an idle 2-core host, 305 s seen with two slots on one loaded by other jobs.
WARM_UP_LIMIT_S = 900


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def wait_for(predicate: Callable[[], bool], what: str, proc: subprocess.Popen, log: Path,
             limit_s: float = STARTUP_LIMIT_S) -> None:
    """Poll predicate until true; raise with the log's tail if proc exits first or limit_s passes."""
    deadline = time.monotonic() + limit_s
    while not predicate():
        if proc.poll() is not None:
            raise RuntimeError(f"{what} exited with {proc.returncode}:\n{log.read_text(errors='replace')[-3000:]}")
        if time.monotonic() > deadline:
            raise RuntimeError(f"{what} did not start:\n{log.read_text(errors='replace')[-3000:]}")
        time.sleep(0.2)


def start_worker(env: dict, queues: str, log: Path, *, warm: bool = False) -> subprocess.Popen:
    """A real Celery worker process (prefork, WORKER_CONCURRENCY slots from `env`, else one per core), returned once
    it says it is ready; with `warm`, once its case slots are warm and it consumes its case queues (until then it
    takes no case: worker.warm_gate)."""
    # lazy: worker.celery_app loads Celery and makes filesystem-broker folders on import; only start_worker needs it
    from worker.celery_app import worker_argv
    from worker.warm_gate import OPENED

    command = worker_argv(queues.split(","), name=f"{queues.replace(',', '-')}-{uuid.uuid4().hex[:6]}@%h",
                          heartbeat=False)
    offset = log.stat().st_size if log.exists() else 0  # a log appended to again: only this worker's lines count

    def said(words: str) -> bool:
        with log.open("rb") as f:
            f.seek(offset)
            return words in f.read().decode(errors="replace")

    proc = subprocess.Popen(command, cwd=ROOT, env=env, stdout=log.open("ab"), stderr=subprocess.STDOUT,
                            start_new_session=True)
    wait_for(lambda: said(" ready."), "celery worker", proc, log)
    if warm:
        wait_for(lambda: said(OPENED), "celery worker's warm-up", proc, log, limit_s=WARM_UP_LIMIT_S)
    return proc


def start_api(env: dict, port: int, log: Path, *, workers: int = 1, cpus: str | None = None) -> subprocess.Popen:
    """The API under uvicorn on 127.0.0.1:port (`workers` processes, as deployed), returned once /v1/health answers;
    with `cpus` (a taskset list), every API process runs on those CPUs only."""
    pin = ["taskset", "-c", cpus] if cpus else []
    proc = subprocess.Popen([*pin, sys.executable, "-m", "uvicorn", "grader.main:app", "--host", "127.0.0.1",
                             "--port", str(port), "--log-level", "warning", "--workers", str(workers)],
                            cwd=ROOT, env=env,
                            stdout=log.open("ab"), stderr=subprocess.STDOUT, start_new_session=True)

    def healthy() -> bool:
        try:
            return httpx.get(f"http://127.0.0.1:{port}/v1/health", timeout=1).status_code == 200
        except httpx.HTTPError:
            return False

    wait_for(healthy, "API", proc, log)
    return proc


def stop(proc: subprocess.Popen) -> None:
    """Stop a process group this session started (SIGTERM, then SIGKILL)."""
    if proc.poll() is not None:
        return
    os.killpg(proc.pid, signal.SIGTERM)
    try:
        proc.wait(timeout=30)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()


def children(pid: int) -> list[int]:
    """Direct child pids of pid (Linux /proc)."""
    out = []
    for task in Path(f"/proc/{pid}/task").glob("*"):
        with contextlib.suppress(OSError):
            out += [int(c) for c in (task / "children").read_text().split()]
    return out
