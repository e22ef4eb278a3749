"""`grader run` says what its worker does before the first case (issue 43): compiling the kernels on a first run, then
warming the slots; never a silent wait of minutes."""

from __future__ import annotations

import subprocess
import sys
import threading
import time

from grader import embedded
from grader.core import warmth


def test_the_embedded_service_says_it_compiles_then_warms_then_stops_saying_once_the_worker_consumes(
        tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(warmth.settings, "data_dir", tmp_path)
    monkeypatch.setattr(warmth.settings, "broker_url", "filesystem://")
    worker = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    slots = dict(name="embedded@host", queues=("cpu", "grade"), slots=2, started_at=time.time())
    warmth.record(warmth.WorkerWarmth(warm=0, **slots))
    warmth.record_compiling(warmth.Compiling(backend="cpu", started_at=time.time() - 200, estimate_s=120.0, pid=1,
                                             first=True))

    def worker_goes_on() -> None:
        time.sleep(0.6)
        warmth.compiling_done()
        warmth.record(warmth.WorkerWarmth(warm=1, **slots))
        time.sleep(0.6)
        warmth.record(warmth.WorkerWarmth(warm=2, warm_s=12.0, **slots))

    thread = threading.Thread(target=worker_goes_on)
    thread.start()
    try:
        embedded.show_warm_up(worker, poll_s=0.05, every_s=0.3)
    finally:
        thread.join()
        worker.kill()
    lines = capsys.readouterr().out.splitlines()
    compiling = "compiling the simulation kernels (first run on this machine, about 2 minutes; once per machine) ..."
    assert lines[0] == compiling, lines
    assert any(line.startswith(compiling + " 20") and "longer than estimated" in line for line in lines), lines
    warming = [line for line in lines if line.startswith("warming 2 case slots")]
    assert warming and lines.index(warming[0]) > 0, lines


def test_a_worker_that_dies_while_warming_ends_the_wait(tmp_path, monkeypatch):
    monkeypatch.setattr(warmth.settings, "data_dir", tmp_path)
    monkeypatch.setattr(warmth.settings, "broker_url", "filesystem://")
    worker = subprocess.Popen([sys.executable, "-c", "raise SystemExit(1)"])
    started = time.monotonic()
    embedded.show_warm_up(worker, poll_s=0.05)
    assert time.monotonic() - started < 10
