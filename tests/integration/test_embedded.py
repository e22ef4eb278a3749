"""`grader run --exit-after-grading`: the embedded default grades the example sheet with no Redis or PostgreSQL; and
`grader run` stopped by SIGTERM leaves no process of its own behind."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time

import psutil
import pytest

from rubric import load_rubric
from tests import services

pytestmark = [pytest.mark.slow]


def test_embedded_run_grades_the_example_sheet_without_servers(tmp_path):
    env = {k: v for k, v in os.environ.items() if k not in ("DATABASE_URL", "BROKER_URL", "ARTIFACTS_DIR")}
    env.update(DATA_DIR=str(tmp_path / "data"), PYTHONPATH=str(services.ROOT))
    port = services.free_port()
    done = subprocess.run(
        [sys.executable, "-c", "from grader.cli.service import run; run()", "--exit-after-grading", "--port", str(port)],
        cwd=services.ROOT, env=env, capture_output=True, text=True, timeout=900,
    )
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    out = done.stdout
    assert "database sqlite:///" in out and "broker filesystem://" in out
    assert f"API at http://127.0.0.1:{port}" in out and "GRADE " in out
    report = tmp_path / "data" / "reports" / "submission-1" / "grade.json"
    assert f"report: {report}" in out
    grade = json.loads(report.read_text())
    # The example sheet is the reference answer: every item of the current rubric at its full points.
    rubric = load_rubric("L03")
    full_marks = sum(item.points for item in rubric.items)
    assert (grade["rubric_version"], grade["rubric_hash"]) == (rubric.version, rubric.content_hash)
    assert {i["id"]: i["max_score"] for i in grade["items"]} == {item.id: item.points for item in rubric.items}
    short = [(i["id"], i["verdict"], i["feedback"]) for i in grade["items"]
             if i["verdict"] != "credit" or i["score"] != i["max_score"]]
    assert not short, short
    assert grade["total"] == grade["max_total"] == full_marks
    assert f"GRADE {full_marks:g} / {full_marks:g}" in out
    runs = json.loads((report.parent / "case-runs.json").read_text())
    assert runs and all(r["status"] == "done" and r["provenance"]["actual_backend"] == "cpu" for r in runs)
    assert (tmp_path / "data" / "grader.db").is_file()


def _cmdline(process: psutil.Process) -> str:
    try:
        return " ".join(process.cmdline())
    except psutil.Error:
        return ""


def _running(process: psutil.Process) -> bool:
    try:
        return process.is_running() and process.status() != psutil.STATUS_ZOMBIE
    except psutil.Error:
        return False


def _with_data_dir(data_dir: str) -> list[psutil.Process]:
    """Every live process on this machine whose environment names this DATA_DIR (also one reparented to init)."""
    found = []
    for process in psutil.process_iter():
        try:
            if process.environ().get("DATA_DIR") == data_dir and _running(process):
                found.append(process)
        except psutil.Error:
            pass
    return found


def test_sigterm_while_the_worker_warms_up_stops_every_process_it_started(tmp_path):
    """Issue 44, finding 6b: SIGTERM before the first grade left the Celery worker and its warm case processes
    running. Stopped here as soon as a warm case process exists (nothing compiled or measured: a private copy of the
    kernel cache, since its processes are killed)."""
    data_dir = str(tmp_path / "data")
    env = {k: v for k, v in os.environ.items() if k not in ("DATABASE_URL", "BROKER_URL", "ARTIFACTS_DIR")}
    env.update(DATA_DIR=data_dir, PYTHONPATH=str(services.ROOT), **services.private_kernel_cache(tmp_path))
    log_path = tmp_path / "run.log"
    with log_path.open("wb") as log:
        embedded = subprocess.Popen(
            [sys.executable, "-c", "from grader.cli.service import run; run()", "--port", str(services.free_port())],
            cwd=services.ROOT, env=env, stdout=log, stderr=subprocess.STDOUT)
    seen: dict[int, psutil.Process] = {}
    try:
        deadline = time.monotonic() + 300
        while not any("worker.warm_process" in _cmdline(p) for p in seen.values()):
            assert embedded.poll() is None and time.monotonic() < deadline, log_path.read_text()[-3000:]
            for child in psutil.Process(embedded.pid).children(recursive=True):
                seen.setdefault(child.pid, child)
            time.sleep(0.1)
        kinds = {"celery" if "celery" in _cmdline(p) else "warm" if "warm_process" in _cmdline(p) else "other"
                 for p in seen.values()}
        assert {"celery", "warm"} <= kinds, [_cmdline(p) for p in seen.values()]
        embedded.send_signal(signal.SIGTERM)
        embedded.wait(timeout=120)
        left = [(p.pid, _cmdline(p)) for p in seen.values() if _running(p)]
        assert not left, left
        assert not _with_data_dir(data_dir)
        assert embedded.returncode == 130, log_path.read_text()[-3000:]
    finally:  # what the old code left running, stopped by its pid
        for process in [*seen.values(), *_with_data_dir(data_dir)]:
            if _running(process):
                process.kill()
        if embedded.poll() is None:
            embedded.kill()
            embedded.wait()
