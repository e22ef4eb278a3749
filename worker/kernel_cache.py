"""Genesis' kernel cache: compiled once per machine (`compile_once`), and a lock file left by a killed process removed
once it is surely stale.

One compile per machine: every warm case slot that warms up (worker.warm_process) loads the lesson's kernels from the
cache. On a fresh machine the cache is empty, and two slots starting together each compiled every kernel, on the same
cores (issue 43: `make run` spent 17 minutes warming 2 slots on a loaded 2-core machine, 4 minutes of CPU each).
Now the first slot to take a file lock compiles in a short-lived child process (quadrants writes what it compiled to
the cache only as a process ends, in Genesis' atexit `destroy`), leaves a marker naming the engine's versions and the
backend, and lets go; the other slots wait on the lock, find the marker and load the kernels from the cache.

quadrants (the compiler under Genesis 1.3.3) keeps compiled kernels in an offline cache guarded by `qdcache.lock`, a
file that exists while a process reads or writes the cache. A process killed meanwhile (a case past its time limit,
a worker SIGKILLed) leaves the file behind, and every later process fails to take the lock and compiles its kernels
anew (~100 s on CPU) until someone deletes it; quadrants only says "You can remove this .lock file manually". Seen on
the development machine: a lock left by a killed case process made every case process compile for an hour.
"""

from __future__ import annotations

import hashlib
import json
import os
import subprocess
import sys
import time
from importlib import metadata
from pathlib import Path

from filelock import FileLock, Timeout

from grader.core import warmth

# A process holds the lock for the seconds of a cache read or write; one older than this was left by a dead one.
STALE_AFTER_S = 600.0
# What a first compile is said to take before this machine has done one: the lesson's six scene structures on the
# 2-core development machine, idle, took about 100 s (DESIGN.md); said as "about 2 minutes".
FIRST_COMPILE_ESTIMATE_S = 120.0
# A slot waits this long for another process's compile before compiling its kernels itself.
COMPILE_WAIT_S = 1800.0
COMPILING = "compiling the simulation kernels"  # the worker log's words when a compile starts


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


def _versions_key(backend: str) -> str:
    versions = []
    for dist in ("genesis-world", "quadrants", "torch"):
        try:
            versions.append(f"{dist}-{metadata.version(dist)}")
        except metadata.PackageNotFoundError:
            versions.append(f"{dist}-none")
    return "_".join([backend, *versions, _scenes_key()])


def _scenes_key() -> str:
    """The installed lessons' warm-up scenes, digested: a lesson installed since the kernels were compiled (or a
    scene of one changed) compiles its kernels once more, rather than in the first case process that meets them."""
    from worker.warm_process import warm_up_cases

    text = json.dumps([[name, spec.model_dump(mode="json")] for name, spec in warm_up_cases()], sort_keys=True)
    return "scenes-" + hashlib.sha256(text.encode()).hexdigest()[:12]


def compiled_marker(backend: str) -> Path:
    """The file that says the lesson's kernels for `backend` and these engine versions are in the cache; it lives in
    the cache folder, so removing the cache removes it too."""
    return cache_folder() / f"grader-compiled-{_versions_key(backend)}.json"


def compile_once(backend: str, *, command: list[str] | None = None, log=None) -> dict | None:
    """Make sure the lesson's kernels for `backend` are in this machine's cache, compiling them at most once per
    machine: under a file lock, the first caller runs `command` (default: this module's main, which warms up every
    scene structure of the lesson in a child process and exits, so the cache is written) and leaves the marker; the
    others wait, then find it. What it does goes to `log` (stderr: the worker's log) and, while compiling, to the
    broker's warmth store (`warmth.compiling`: `grader run`, `grader status` and the progress page say so).

    Returns {"compiled_s": seconds} when this call compiled, {"waited_s": seconds} when it waited for another
    process's compile, None when the cache was already filled. A failed compile leaves no marker and says why in the
    log: the slot's own warm-up then meets the same fault, and its first case records it."""
    log = log or sys.stderr
    marker = compiled_marker(backend)
    if marker.exists():
        return None
    marker.parent.mkdir(parents=True, exist_ok=True)
    lock = FileLock(str(cache_folder() / f"grader-compile-{backend}.lock"))
    started = time.time()
    try:
        lock.acquire(timeout=0)
    except Timeout:
        print(f"waiting for another process {COMPILING} (lock file {lock.lock_file})", file=log, flush=True)
        try:
            lock.acquire(timeout=COMPILE_WAIT_S)
        except Timeout:
            print(f"gave up waiting after {COMPILE_WAIT_S:.0f} s: this process compiles what it needs", file=log,
                  flush=True)
            return {"waited_s": round(time.time() - started, 3)}
    try:
        if marker.exists():
            return {"waited_s": round(time.time() - started, 3)}
        return _compile(backend, marker, command or [sys.executable, "-m", "worker.kernel_cache", backend], log)
    finally:
        lock.release()


def _compile(backend: str, marker: Path, command: list[str], log) -> dict:
    last = _last_compile_s()
    estimate = last or FIRST_COMPILE_ESTIMATE_S
    said = (f"about {estimate:.0f} s, as the last compile here" if last
            else f"first run on this machine, about {estimate / 60:.0f} minutes")
    print(f"{COMPILING} for {backend} ({said}) ...", file=log, flush=True)
    started = time.time()
    state = warmth.Compiling(backend=backend, started_at=started, estimate_s=estimate, pid=os.getpid(),
                             first=last is None)
    child = subprocess.Popen(command, stdout=log, stderr=log)
    try:
        while child.poll() is None:
            _try(warmth.record_compiling, state)
            try:
                child.wait(timeout=warmth.RENEW_S)
            except subprocess.TimeoutExpired:
                pass
    finally:
        if child.poll() is None:  # this process is being stopped: so is its compile
            child.terminate()
            child.wait()
        _try(warmth.compiling_done)
    seconds = time.time() - started
    if child.returncode != 0:
        print(f"{COMPILING} failed after {seconds:.1f} s (exit status {child.returncode}); no marker left",
              file=log, flush=True)
        return {"compiled_s": None}
    marker.write_text(json.dumps({"backend": backend, "compiled_s": round(seconds, 3), "at": started}))
    print(f"compiled the simulation kernels for {backend} in {seconds:.1f} s; every slot loads them from "
          f"{cache_folder()}", file=log, flush=True)
    return {"compiled_s": round(seconds, 3)}


def _last_compile_s() -> float | None:
    for path in sorted(cache_folder().glob("grader-compiled-*.json")):
        try:
            return float(json.loads(path.read_text())["compiled_s"])
        except (OSError, ValueError, KeyError, TypeError):
            continue
    return None


def _try(action, *args) -> None:
    try:
        action(*args)
    except Exception as exc:  # noqa: BLE001 - the record is for people watching; the compile goes on without it
        print(f"could not record the compile's progress: {exc}", file=sys.stderr, flush=True)


def main(backend: str) -> int:
    """The compile itself, in a process of its own: every scene structure of the lesson built and run on `backend`,
    then a normal exit, in which Genesis writes the compiled kernels to the cache."""
    from .warm_process import warm_up  # lazy: imports Genesis (worker.engine) only in this child process

    line = warm_up(backend, reuse=False, said="kernels compiled by a warm-up")  # not a slot's WARM_UP_DONE
    return 0 if line["ok"] else 1


if __name__ == "__main__":
    sys.exit(main(sys.argv[1]))
