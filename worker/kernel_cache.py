"""Genesis' kernel cache: a lock file left by a killed process is removed once it is surely stale.

quadrants (the compiler under Genesis 1.3.3) keeps compiled kernels in an offline cache guarded by `qdcache.lock`, a
file that exists while a process reads or writes the cache. A process killed meanwhile (a case past its time limit,
a worker SIGKILLed) leaves the file behind, and every later process fails to take the lock and compiles its kernels
anew (~100 s on CPU) until someone deletes it; quadrants only says "You can remove this .lock file manually". Seen on
the development machine: a lock left by a killed case process made every case process compile for an hour.
"""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path

# A process holds the lock for the seconds of a cache read or write; one older than this was left by a dead one.
STALE_AFTER_S = 600.0


def cache_folder() -> Path:
    """Where quadrants keeps its cache: QD_OFFLINE_CACHE_FILE_PATH, else ~/.cache/quadrants/qdcache (XDG-aware)."""
    if path := os.environ.get("QD_OFFLINE_CACHE_FILE_PATH"):
        return Path(path)
    return Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "quadrants" / "qdcache"


def remove_stale_lock(now: float | None = None) -> Path | None:
    """Remove the cache's lock file if it is older than STALE_AFTER_S; says so on stderr. Returns what it removed."""
    lock = cache_folder() / "kernel_compilation_manager" / "qdcache.lock"
    try:
        age = (time.time() if now is None else now) - lock.stat().st_mtime
    except FileNotFoundError:
        return None
    if age < STALE_AFTER_S:
        return None
    lock.unlink(missing_ok=True)
    print(f"removed a stale Genesis kernel-cache lock ({lock}, {age:.0f} s old): left by a killed process, it made "
          "every case process compile its kernels anew", file=sys.stderr)
    return lock
