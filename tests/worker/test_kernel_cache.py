"""A kernel-cache lock left by a killed process is removed once stale, and never while a process may hold it."""

from __future__ import annotations

import os
import time
from pathlib import Path

from worker.kernel_cache import STALE_AFTER_S, remove_stale_lock


def _lock(tmp_path, monkeypatch, age_s: float):
    monkeypatch.setenv("QD_OFFLINE_CACHE_FILE_PATH", str(tmp_path))
    lock = tmp_path / "kernel_compilation_manager" / "qdcache.lock"
    lock.parent.mkdir()
    lock.touch()
    os.utime(lock, (lock.stat().st_mtime - age_s,) * 2)
    return lock


def test_a_lock_older_than_any_cache_write_is_removed(tmp_path, monkeypatch, capsys):
    lock = _lock(tmp_path, monkeypatch, STALE_AFTER_S + 60)
    assert remove_stale_lock() == lock
    assert not lock.exists()
    assert "stale Genesis kernel-cache lock" in capsys.readouterr().err


def test_a_recent_lock_is_left_to_its_process(tmp_path, monkeypatch):
    lock = _lock(tmp_path, monkeypatch, 5)
    assert remove_stale_lock() is None
    assert lock.exists()


def test_no_lock_no_action(tmp_path, monkeypatch):
    monkeypatch.setenv("QD_OFFLINE_CACHE_FILE_PATH", str(tmp_path))
    assert remove_stale_lock() is None


def test_a_warm_case_process_stopped_with_sigterm_exits_through_python_so_genesis_saves_its_kernels():
    """Genesis writes the kernels it compiled to the offline cache in its atexit `destroy`, which the signal's default
    action skips: a worker stopped with SIGTERM to its process group lost them, and the next worker compiled again."""
    import signal

    from worker.case_process import WarmCaseProcess

    warm = WarmCaseProcess()
    warm._start()
    try:
        deadline = time.monotonic() + 60
        while not _catches(warm._proc.pid, signal.SIGTERM):  # its handler is set (Linux: /proc/PID/status)
            assert warm._proc.poll() is None and time.monotonic() < deadline
            time.sleep(0.05)
        warm._proc.send_signal(signal.SIGTERM)
        assert warm._proc.wait(timeout=30) == 128 + signal.SIGTERM  # SystemExit(143), not killed (-15)
    finally:
        warm.close()


def _catches(pid: int, signum: int) -> bool:
    """Whether process pid has a handler for signum (its SigCgt mask)."""
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("SigCgt:"):
            return bool(int(line.split()[1], 16) >> (signum - 1) & 1)
    return False


_RACER = """
import json, sys
from worker.kernel_cache import compile_once
command = [sys.executable, "-c", "import pathlib, time; p = pathlib.Path(sys.argv[1]); "
           "p.write_text(p.read_text() + 'x') if p.exists() else p.write_text('x'); time.sleep(2)".replace(
           "sys.argv[1]", repr(sys.argv[1]))]
print(json.dumps(compile_once("cpu", command=command)))
"""


def test_two_slots_starting_on_a_fresh_machine_compile_the_kernels_once(tmp_path, monkeypatch):
    """Issue 43: both warm slots of a fresh worker compiled every kernel at once. The first to take the lock compiles
    (here a stand-in command that counts its runs: the real compile is Genesis' ~100 s, measured by `make run` on a
    fresh cache), says so in the warmth store while it runs, and leaves the marker; the other waits, then loads."""
    import json
    import subprocess
    import sys

    from grader.core import warmth

    cache = tmp_path / "qdcache"
    data = tmp_path / "data"
    env = dict(os.environ, QD_OFFLINE_CACHE_FILE_PATH=str(cache), DATA_DIR=str(data),
               BROKER_URL="filesystem://", PYTHONPATH=str(Path(__file__).resolve().parents[2]))
    monkeypatch.setenv("QD_OFFLINE_CACHE_FILE_PATH", str(cache))
    runs = tmp_path / "runs"
    racers = [subprocess.Popen([sys.executable, "-c", _RACER, str(runs)], env=env, stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE, text=True) for _ in range(2)]
    seen_compiling = None
    deadline = time.monotonic() + 30
    monkeypatch.setattr(warmth.settings, "data_dir", data)
    monkeypatch.setattr(warmth.settings, "broker_url", "filesystem://")
    while any(r.poll() is None for r in racers) and time.monotonic() < deadline:
        seen_compiling = seen_compiling or warmth.compiling()
        time.sleep(0.1)
    outputs = [r.communicate(timeout=30) for r in racers]
    assert all(r.returncode == 0 for r in racers), outputs
    answers = sorted((json.loads(out.strip().splitlines()[-1]) for out, _ in outputs), key=lambda a: sorted(a))
    assert runs.read_text() == "x", "the compile ran more than once"
    assert [sorted(a) for a in answers] == [["compiled_s"], ["waited_s"]], answers
    assert answers[0]["compiled_s"] >= 2 and answers[1]["waited_s"] >= 1, answers
    logs = "".join(err for _, err in outputs)
    assert "compiling the simulation kernels for cpu (first run on this machine, about 2 minutes)" in logs, logs
    assert "waiting for another process compiling the simulation kernels" in logs, logs
    assert seen_compiling is not None and seen_compiling.backend == "cpu" and seen_compiling.estimate_s == 120.0
    assert warmth.compiling() is None, "the compile's record outlived it"
    marker = json.loads(next(cache.glob("grader-compiled-cpu_genesis-world-*.json")).read_text())
    assert marker["compiled_s"] >= 2
    # A third slot, later, finds the marker: no compile, no wait.
    again = subprocess.run([sys.executable, "-c", _RACER, str(runs)], env=env, capture_output=True, text=True,
                           timeout=30)
    assert json.loads(again.stdout.strip().splitlines()[-1]) is None and runs.read_text() == "x"


def test_a_failed_compile_leaves_no_marker_and_says_why(tmp_path, monkeypatch):
    import sys

    from worker.kernel_cache import compile_once, compiled_marker

    monkeypatch.setenv("QD_OFFLINE_CACHE_FILE_PATH", str(tmp_path / "qdcache"))
    log = tmp_path / "log"
    with log.open("w") as out:
        assert compile_once("cpu", command=[sys.executable, "-c", "raise SystemExit(3)"], log=out) == {
            "compiled_s": None}
    assert not compiled_marker("cpu").exists()
    assert "failed after" in log.read_text() and "exit status 3" in log.read_text()
