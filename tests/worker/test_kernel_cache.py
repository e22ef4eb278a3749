"""A kernel-cache lock left by a killed process is removed once stale, and never while a process may hold it."""

from __future__ import annotations

import os

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
