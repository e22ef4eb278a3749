"""Which workers are warm: each Celery worker's record of its case slots (warm or warming), kept in the broker's own
store with a short lifetime, and how long the last warm-up took; written by the worker (worker.warm_gate), read by
/metrics, `grader status` and the progress page.

In the broker, not the database: a worker on another host shares only the database and the broker with the API, and a
record that lives only while its worker renews it needs no table and no clean-up after a killed worker. On Redis a key
per worker expires RECORD_TTL_S after its last renewal; on the embedded filesystem broker a file per worker counts
while its modification time is that recent. Another broker keeps no record: nothing is known (None).
"""

from __future__ import annotations

import contextlib
import json
import os
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import redis

from grader.core.settings import settings

__all__ = ["RECORD_TTL_S", "RENEW_S", "Compiling", "WorkerWarmth", "compiling", "compiling_done", "forget",
           "last_warm_up_s", "live", "record", "record_compiling", "record_warm_up", "warm_backends"]

RENEW_S = 5.0  # a worker renews its record this often
RECORD_TTL_S = 3 * RENEW_S  # and it counts for this long after its last renewal (a killed worker drops out)
_PREFIX = "grader:warmth:"
_LAST = _PREFIX + "last-warm-up"
_COMPILING = _PREFIX + "compiling"


@dataclass(frozen=True)
class WorkerWarmth:
    """One worker as it last said: its case slots, how many are warm, and since when it has been starting (epoch s).
    `warm_s` is how long its warm-up took (None while warming); it consumes its case queues only once every slot is
    warm (worker.warm_gate)."""

    name: str
    queues: tuple[str, ...]
    slots: int
    warm: int
    started_at: float
    warm_s: float | None = None

    @property
    def consuming(self) -> bool:
        return self.warm_s is not None

    @property
    def warming(self) -> int:
        return self.slots - self.warm


def _folder() -> Path:
    return settings.data_dir.absolute() / "broker" / "warmth"


def _redis():
    return redis.Redis.from_url(settings.broker_url, socket_timeout=2, socket_connect_timeout=2)


def _kind() -> str | None:
    url = settings.broker_url
    return "redis" if url.startswith("redis") else "filesystem" if url.startswith("filesystem") else None


def _safe(name: str) -> str:
    return "".join(c if c.isalnum() or c in "-_.@" else "_" for c in name)


def record(worker: WorkerWarmth) -> None:
    """Store (or renew) a worker's record; it lapses RECORD_TTL_S after the last call."""
    body = json.dumps(asdict(worker))
    if _kind() == "redis":
        with contextlib.closing(_redis()) as client:
            client.set(_PREFIX + "worker:" + worker.name, body, ex=int(RECORD_TTL_S))
    elif _kind() == "filesystem":
        folder = _folder()
        folder.mkdir(parents=True, exist_ok=True)
        path = folder / f"{_safe(worker.name)}.json"
        temp = path.with_suffix(f".{os.getpid()}.tmp")
        temp.write_text(body)
        temp.replace(path)


def forget(name: str) -> None:
    """A worker stopping drops its record at once."""
    if _kind() == "redis":
        with contextlib.closing(_redis()) as client:
            client.delete(_PREFIX + "worker:" + name)
    elif _kind() == "filesystem":
        (_folder() / f"{_safe(name)}.json").unlink(missing_ok=True)


def live() -> list[WorkerWarmth] | None:
    """The records of the workers alive now (renewed within RECORD_TTL_S), by name; None where the broker keeps none."""
    bodies: list[str | bytes] = []
    if _kind() == "redis":
        with contextlib.closing(_redis()) as client:
            keys = sorted(client.scan_iter(match=_PREFIX + "worker:*", count=100))
            bodies = [b for b in (client.mget(keys) if keys else []) if b is not None]
    elif _kind() == "filesystem":
        now = time.time()
        for path in sorted(_folder().glob("*.json")) if _folder().is_dir() else []:
            with contextlib.suppress(OSError):
                if now - path.stat().st_mtime <= RECORD_TTL_S:
                    bodies.append(path.read_text())
    else:
        return None
    out = []
    for body in bodies:
        with contextlib.suppress(ValueError, TypeError):
            data = json.loads(body)
            out.append(WorkerWarmth(**{**data, "queues": tuple(data["queues"])}))
    return sorted(out, key=lambda w: w.name)


def record_warm_up(seconds: float) -> None:
    """Keep how long a worker's warm-up took, from its start to all its slots warm (kept until the next one)."""
    if _kind() == "redis":
        with contextlib.closing(_redis()) as client:
            client.set(_LAST, f"{seconds:.3f}")
    elif _kind() == "filesystem":
        _folder().mkdir(parents=True, exist_ok=True)
        (_folder() / "last-warm-up").write_text(f"{seconds:.3f}")


def last_warm_up_s() -> float | None:
    """How long the last finished warm-up took; None if none finished yet (or the broker keeps none)."""
    raw = None
    if _kind() == "redis":
        with contextlib.closing(_redis()) as client:
            raw = client.get(_LAST)
    elif _kind() == "filesystem":
        with contextlib.suppress(OSError):
            raw = (_folder() / "last-warm-up").read_text()
    try:
        return float(raw) if raw is not None else None
    except ValueError:
        return None


def warm_backends(workers: list[WorkerWarmth]) -> tuple[set[str], set[str]]:
    """The queues some live worker consumes (warm), and those only warming workers listen on."""
    warm = {q for w in workers if w.consuming for q in w.queues}
    warming = {q for w in workers if not w.consuming for q in w.queues} - warm
    return warm, warming


@dataclass(frozen=True)
class Compiling:
    """A case process compiling the lesson's simulation kernels into the machine's kernel cache (worker.kernel_cache:
    one process per machine does it, the other slots wait for it): since when (epoch s), and how long it should take
    (the last compile on this machine, or a first-run estimate)."""

    backend: str
    started_at: float
    estimate_s: float
    pid: int
    first: bool = False  # no compile finished on this machine before: the estimate is the first-run one


def record_compiling(state: Compiling) -> None:
    """Store (or renew) the compile's record; it lapses RECORD_TTL_S after the last call, so a killed compile drops out."""
    body = json.dumps(asdict(state))
    if _kind() == "redis":
        with contextlib.closing(_redis()) as client:
            client.set(_COMPILING, body, ex=int(RECORD_TTL_S))
    elif _kind() == "filesystem":
        _folder().mkdir(parents=True, exist_ok=True)
        temp = _folder() / f"compiling.{os.getpid()}.tmp"
        temp.write_text(body)
        temp.replace(_folder() / "compiling")


def compiling_done() -> None:
    if _kind() == "redis":
        with contextlib.closing(_redis()) as client:
            client.delete(_COMPILING)
    elif _kind() == "filesystem":
        (_folder() / "compiling").unlink(missing_ok=True)


def compiling() -> Compiling | None:
    """The compile going on now, if a live process renewed its record within RECORD_TTL_S; else None."""
    raw = None
    if _kind() == "redis":
        with contextlib.closing(_redis()) as client:
            raw = client.get(_COMPILING)
    elif _kind() == "filesystem":
        path = _folder() / "compiling"
        with contextlib.suppress(OSError):
            if time.time() - path.stat().st_mtime <= RECORD_TTL_S:
                raw = path.read_text()
    if raw is None:
        return None
    try:
        return Compiling(**json.loads(raw))
    except (ValueError, TypeError):
        return None
