"""A worker starting on a host re-sends the runs that processes on that host held when they died
(grader.core.lifecycle.dead_here): a process that exited but was not reaped yet (a zombie) is dead too."""

from __future__ import annotations

import subprocess
import sys
import time

from grader.core import lifecycle


def test_a_live_process_is_alive_and_an_unreaped_dead_one_is_not():
    live = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(30)"])
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    try:
        deadline = time.monotonic() + 20
        while not lifecycle._zombie(dead.pid):  # exited, not yet waited for: it still answers signal 0
            assert time.monotonic() < deadline, "the child never became a zombie"
            time.sleep(0.05)
        assert lifecycle._pid_alive(live.pid) is True
        assert lifecycle._pid_alive(dead.pid) is False
    finally:
        live.kill()
        live.wait()
        dead.wait()
    assert lifecycle._pid_alive(dead.pid) is False  # reaped: gone
    assert lifecycle._pid_alive(None) is False
