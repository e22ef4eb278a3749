"""The write epoch and the validators kept beside it, so that a conditional read that has not changed is answered
304 with no database query (grader.web.fresh).

The **write epoch** is one value in the shared store that every process (API, worker, reconciler, CLI) changes after
each commit that wrote anything (grader.core.db hooks it under every engine). Coarse on purpose: no writer can be
forgotten, because none is named. A **validator entry** says "this reader's answer at this address had ETag E when
the epoch was N, and nothing but a write can change it before `not_after`": the epoch is read before the request's
first database read, so a write committed after that read changes the epoch and retires the entry.

In the broker's own store, like grader.core.warmth: on Redis the epoch is one key (INCR) and each entry a key that
expires at its `not_after`; on the embedded filesystem broker the epoch is a file replaced by a fresh unique value
and each entry a file (read back only while its `not_after` is ahead). Any other broker, or a store that fails,
keeps nothing: every read takes the database path, and a failed bump is retried by the next one.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import logging
import os
import random
import threading
import time
import uuid
from datetime import datetime, timedelta
from pathlib import Path

import redis

from grader.core import clock
from grader.core.settings import settings

__all__ = ["ENTRY_TTL_S", "Entry", "bump", "entry_key", "read", "read_epoch", "remember"]

log = logging.getLogger(__name__)

# The longest an entry is trusted without a full read (a last guard; most entries end sooner: see grader.web.fresh).
ENTRY_TTL_S = 60.0
# Key prefix on Redis and folder name under data_dir/broker on the embedded store (a test takes one of its own).
PREFIX = "grader:fresh:"
TIMEOUT_S = 0.25  # a store that does not answer within this falls back to the database path


class Entry(dict):
    """{"etag", "epoch", "not_after" (ISO instant, the service's clock)}."""


def _kind() -> str | None:
    url = settings.broker_url
    return "redis" if url.startswith("redis") else "filesystem" if url.startswith("filesystem") else None


_clients: dict[tuple[int, str], redis.Redis] = {}
_clients_lock = threading.Lock()


def _redis() -> redis.Redis:
    """One client (with its connection pool) per process and broker URL: a round trip, not a connection, per read."""
    key = (os.getpid(), settings.broker_url)
    client = _clients.get(key)
    if client is None:
        with _clients_lock:
            client = _clients.get(key) or redis.Redis.from_url(
                settings.broker_url, socket_timeout=TIMEOUT_S, socket_connect_timeout=TIMEOUT_S)
            _clients[key] = client
    return client


def _folder() -> Path:
    return settings.data_dir.absolute() / "broker" / PREFIX.strip(":").replace(":", "-")


def _epoch_key() -> str:
    return PREFIX + "epoch"


def entry_key(*parts: str) -> str:
    """The entry's key over everything the answer varies by (the reader's credential among them: only hashed)."""
    return hashlib.sha256("\x00".join(parts).encode()).hexdigest()


# -- the epoch ---------------------------------------------------------------------------------------------------

_owed = threading.Event()  # a bump that failed: retried by the next bump or read, at most once per RETRY_S
RETRY_S = 1.0  # after the store failed, this process leaves it alone this long (a hung store costs one timeout)
_failed_at = [float("-inf")]  # when the store last failed (time.monotonic)


def _resting() -> bool:
    return time.monotonic() - _failed_at[0] < RETRY_S


def _failed() -> None:
    _failed_at[0] = time.monotonic()


def bump() -> None:
    """After a commit that wrote: every entry read under the old epoch stops being trusted."""
    if _resting():  # the store failed a moment ago: owed, and paid by the first bump or read after the rest
        _owed.set()
        return
    kind = _kind()
    try:
        if kind == "redis":
            _redis().incr(_epoch_key())
        elif kind == "filesystem":
            folder = _folder()
            folder.mkdir(parents=True, exist_ok=True)
            temp = folder / f"epoch.{os.getpid()}.{threading.get_ident()}.tmp"
            temp.write_text(uuid.uuid4().hex)  # a value never seen before: two writers need no lock
            temp.replace(folder / "epoch")
        _owed.clear()
    except (redis.RedisError, OSError) as exc:
        _owed.set()
        _failed()
        log.error("write epoch not bumped (%s): validators read before this commit may be confirmed until their "
                  "not_after (at most %.0f s)", exc, ENTRY_TTL_S)


def read_epoch() -> str | None:
    """The current epoch ("" before any write), None where the store keeps none or fails."""
    kind = _kind()
    try:
        if kind == "redis":
            value = _redis().get(_epoch_key())
            return value.decode() if value is not None else ""
        if kind == "filesystem":
            try:
                return (_folder() / "epoch").read_text()
            except FileNotFoundError:
                return ""
    except (redis.RedisError, OSError):
        return None
    return None


# -- entries -----------------------------------------------------------------------------------------------------

def read(key: str) -> tuple[str | None, Entry | None]:
    """(epoch now, the entry at `key` if any) in one round trip; (None, None) where the store keeps none or fails,
    and while this process owes a bump it could not make (nothing is trusted until it is made)."""
    if _resting():
        return None, None
    if _owed.is_set():
        bump()
        if _owed.is_set():
            return None, None
    kind = _kind()
    raw = None
    try:
        if kind == "redis":
            epoch, raw = _redis().mget([_epoch_key(), PREFIX + "v:" + key])
            epoch = epoch.decode() if epoch is not None else ""
        elif kind == "filesystem":
            folder = _folder()
            try:
                epoch = (folder / "epoch").read_text()
            except FileNotFoundError:
                epoch = ""
            with contextlib.suppress(FileNotFoundError):
                raw = (folder / "v" / key).read_text()
        else:
            return None, None
    except (redis.RedisError, OSError):
        _failed()
        return None, None
    entry = None
    if raw:
        with contextlib.suppress(ValueError, TypeError):
            entry = Entry(json.loads(raw))
    return epoch, entry


def valid(entry: Entry | None, epoch: str | None, now: datetime | None = None) -> bool:
    """Whether `entry` may be trusted now: written under this very epoch and before its not_after."""
    if entry is None or epoch is None or entry.get("epoch") != epoch:
        return False
    try:
        return (now or clock.now()) < datetime.fromisoformat(entry["not_after"])
    except (KeyError, TypeError, ValueError):
        return False


def remember(key: str, *, etag: str, epoch: str, not_after: datetime) -> None:
    """Keep the entry until `not_after` (at most ENTRY_TTL_S ahead); a failing store keeps nothing."""
    now = clock.now()
    not_after = min(not_after, now + timedelta(seconds=ENTRY_TTL_S))
    left_ms = int((not_after - now).total_seconds() * 1000)
    if left_ms <= 0:
        return
    body = json.dumps({"etag": etag, "epoch": epoch, "not_after": not_after.isoformat()})
    kind = _kind()
    try:
        if kind == "redis":
            _redis().set(PREFIX + "v:" + key, body, px=left_ms)
        elif kind == "filesystem":
            folder = _folder() / "v"
            folder.mkdir(parents=True, exist_ok=True)
            temp = folder / f"{key}.{os.getpid()}.{threading.get_ident()}.tmp"
            temp.write_text(body)
            temp.replace(folder / key)
            if random.random() < 0.01:
                _sweep(folder)
    except (redis.RedisError, OSError) as exc:
        _failed()
        log.warning("validator not kept (%s)", exc)


def _sweep(folder: Path) -> None:
    """Drop the embedded store's entries older than ENTRY_TTL_S (none can be trusted any more)."""
    old = time.time() - ENTRY_TTL_S - 5
    for path in folder.iterdir():
        with contextlib.suppress(OSError):
            if path.stat().st_mtime < old:
                path.unlink()
