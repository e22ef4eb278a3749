"""A submission's figures, two ways, on the same stored runs (issue 24 item 2): (a) drawn on the server as the lab's
18 PNGs (worker.figures.lab_figures, L03's figures, what `complete_grade` did), (b) served as the compact JSON series the report's
browser charts draw (grader.services.reports.series). For each: server CPU seconds and bytes per submission. And the
report's completion: POST to the lab check stored, against the cases' own time (target: within 1.5x)."""

from __future__ import annotations

import gzip
import json
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import httpx
import psutil
from sqlalchemy.orm import Session

from grader.core.lifecycle import stored_result
from grader.core.models import Submission
from grader.services.reports.series import submission_series
from tools.bench.stats import median
from tools.bench.submission import grading_seconds, reference_sheet, time_submission


def _cpu(pid: int) -> float:
    """User + system CPU seconds of pid and every process under it."""
    root = psutil.Process(pid)
    total = 0.0
    for proc in (root, *root.children(recursive=True)):
        try:
            times = proc.cpu_times()
        except psutil.NoSuchProcess:
            continue
        total += times.user + times.system
    return total


def _pngs(results: dict, repeats: int) -> dict:
    """Draw every figure (no figure cache: a submission whose runs are its own) `repeats` times after one warm-up
    draw (matplotlib's import and font cache load once per worker process, not per submission)."""
    from worker.figures import lab_figures  # matplotlib only for this part

    cpu, wall, size, count = [], [], 0, 0
    for r in range(repeats + 1):
        with tempfile.TemporaryDirectory() as folder:
            c0, w0 = time.process_time(), time.perf_counter()
            paths = lab_figures(results, folder)
            c1, w1 = time.process_time(), time.perf_counter()
            size, count = sum(Path(p).stat().st_size for p in paths), len(paths)
        if r:  # the first draw warms matplotlib up
            cpu.append(c1 - c0)
            wall.append(w1 - w0)
    return {"figures": count, "cpu_s": median(cpu), "wall_s": median(wall), "bytes": size, "cpu_samples_s": cpu}


def _series(stack, submission_id: int, who: str, repeats: int) -> dict:
    """Build the series in process (what one request does, minus HTTP), then fetch them from the running API and
    count that process's CPU per request."""
    cpu = []
    with Session(stack.engine) as session:
        for _ in range(repeats + 1):
            session.expire_all()
            submission = session.get(Submission, submission_id)
            c0 = time.process_time()
            doc = submission_series(submission=submission)
            body = json.dumps(doc, ensure_ascii=False, separators=(",", ":")).encode()
            cpu.append(time.process_time() - c0)
    url = f"{stack.url}/submissions/{submission_id}/series.json"
    headers = {"Authorization": f"Bearer {stack.tokens[who]}"}
    with httpx.Client(headers=headers, timeout=60) as client:
        client.get(url).raise_for_status()  # warm-up
        before, w0 = _cpu(stack.api.pid), time.perf_counter()
        for _ in range(repeats):
            answer = client.get(url)
            answer.raise_for_status()
        api_cpu, api_wall = (_cpu(stack.api.pid) - before) / repeats, (time.perf_counter() - w0) / repeats
    return {"cpu_s": median(cpu[1:]), "bytes": len(body), "gzip_bytes": len(gzip.compress(body)),
            "served_bytes": len(answer.content), "api_cpu_per_request_s": api_cpu, "api_wall_per_request_s": api_wall,
            "runs": len(doc["runs"])}


def bench_figures(stack, repeats: int, log: Callable[[str], None] = print) -> dict:
    """Cold submissions of the reference sheet timed to their complete report; then both ways of figures on the
    last one's stored runs."""
    staff = stack.client("prof")
    sheet = reference_sheet()
    time_submission(stack.client(stack.students[0]), sheet, worker=stack.worker)  # warm the worker up
    cases, complete = [], []
    for r in range(repeats):
        timed = time_submission(staff, sheet, worker=stack.worker, force_rerun=True)
        cases.append(timed.graded_s - grading_seconds(staff, timed.state))
        complete.append(timed.complete_s)
        log(f"  repeat {r + 1}/{repeats}: cases {cases[-1]:.2f} s, report complete {complete[-1]:.2f} s after the "
            f"POST ({complete[-1] / cases[-1]:.2f}x)")
    submission_id = timed.state["id"]
    with Session(stack.engine) as session:
        results = {run.name: stored_result(run) for run in session.get(Submission, submission_id).case_runs}
    png = _pngs(results, repeats)
    log(f"  PNGs: {png['figures']} figures, {png['cpu_s']:.2f} s CPU, {png['bytes'] / 1e6:.2f} MB")
    series = _series(stack, submission_id, "prof", max(repeats, 5))
    log(f"  series: {series['cpu_s'] * 1e3:.1f} ms CPU in process, {series['api_cpu_per_request_s'] * 1e3:.1f} ms "
        f"API CPU per request, {series['bytes'] / 1e3:.1f} kB ({series['gzip_bytes'] / 1e3:.1f} kB gzipped)")
    return {"stack": stack.kind, "repeats": repeats, "submission_id": submission_id,
            "cold_cases_s": median(cases), "cold_complete_s": median(complete),
            "complete_over_cases": median(complete) / median(cases),
            "cases_samples_s": cases, "complete_samples_s": complete, "png": png, "series": series}
