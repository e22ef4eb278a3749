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
