"""One full L03 submission timed from HTTP POST to its stored grade: first on a just-started worker, cold (every
case measured again, force_rerun) and fully reused (every case run reuses a stored measurement)."""

from __future__ import annotations

import time
from collections.abc import Callable
from datetime import UTC, datetime
from pathlib import Path

import yaml

from grader.benchmark.cases import BenchFailure
from grader.benchmark.stats import median

REFERENCE_SHEET = Path(__file__).resolve().parent.parent.parent / "examples" / "l03" / "reference.yaml"
# Safety stop per submission only (a cold kernel cache can take minutes).
WAIT_LIMIT_S = 900


def reference_sheet() -> dict:
    return yaml.safe_load(REFERENCE_SHEET.read_text())


def _utcnow() -> datetime:
    return datetime.now(UTC).replace(tzinfo=None)


def wait_graded(client, submission_id: int, *, poll_s: float = 0.1, worker=None) -> dict:
    """Poll until graded; raise BenchFailure on failed, past WAIT_LIMIT_S, or when `worker` (a Popen) exited."""
    deadline = time.monotonic() + WAIT_LIMIT_S
    while True:
        if worker is not None and worker.poll() is not None:
            raise BenchFailure(f"the worker exited ({worker.returncode}) with submission {submission_id} unfinished")
        state = client.submission(submission_id)
        if state["status"] == "graded":
            return state
        if state["status"] == "failed":
            raise BenchFailure(f"submission {submission_id} failed: {state['error']}")
        if time.monotonic() > deadline:
            raise BenchFailure(f"submission {submission_id} still {state['status']} after {WAIT_LIMIT_S} s")
        time.sleep(poll_s)


def _at(stamp: str) -> datetime:
    """A server timestamp as naive UTC, the clock `_utcnow` reads."""
    at = datetime.fromisoformat(stamp)
    return at.astimezone(UTC).replace(tzinfo=None) if at.tzinfo is not None else at


def graded_after(state: dict, posted_at: datetime) -> float:
    """Seconds from just before the POST to the grade the server stored (its graded_at, same clock)."""
    return (_at(state["graded_at"]) - posted_at).total_seconds()


def grading_seconds(client, state: dict) -> float:
    """Seconds from a graded submission's last case finishing (its 'grading' event) to its stored grade: the rubric,
    the figures and the lab check. The rest of its POST-to-grade time went to its case runs and their queueing."""
    events = client.events(state["id"])
    grading = [e for e in events if e["case_run_id"] is None and e["state"] == "grading"]
    if not grading:
        raise BenchFailure(f"submission {state['id']}: no 'grading' event among {[e['state'] for e in events]}")
    return (_at(state["graded_at"]) - _at(grading[-1]["at"])).total_seconds()


def time_submission(client, sheet: dict, *, worker=None, **options) -> tuple[float, dict]:
    """POST the sheet, wait for its grade; (seconds from POST to stored grade, final state)."""
    posted_at = _utcnow()
    created = client.submit(sheet, **options)
    state = wait_graded(client, created["id"], worker=worker)
    return graded_after(state, posted_at), state


def bench_submission(stack, repeats: int, log: Callable[[str], None] = print) -> dict:
    """First, cold and reused submissions of examples/l03/reference.yaml on one stack, cold and reused interleaved."""
    client = stack.client(stack.students[0])
    sheet = reference_sheet()
    first_s, state = time_submission(client, sheet, worker=stack.worker)
    log(f"  submission on a just-started worker: {first_s:.2f} s ({state['progress']['total']} case runs)")
    cold, reused, cold_cases, cold_grading = [], [], [], []
    for r in range(repeats):
        seconds, state = time_submission(client, sheet, worker=stack.worker, force_rerun=True)
        cold.append(seconds)
        cold_grading.append(grading_seconds(client, state))
        cold_cases.append(seconds - cold_grading[-1])
        log(f"  repeat {r + 1}/{repeats} cold {seconds:.2f} s (cases {cold_cases[-1]:.2f} s, "
            f"grading {cold_grading[-1]:.2f} s)")
        seconds, state = time_submission(client, sheet, worker=stack.worker)
        runs = client.case_runs(state["id"])
        if not all(run["reused_from_id"] for run in runs):
            raise BenchFailure(f"submission {state['id']}: expected every case run reused")
        reused.append(seconds)
        log(f"  repeat {r + 1}/{repeats} reused {seconds:.2f} s")
    return {"stack": stack.kind, "repeats": repeats, "case_runs": state["progress"]["total"], "first_s": first_s,
            "cold_s": median(cold), "reused_s": median(reused), "cold_samples_s": cold, "reused_samples_s": reused,
            # the cold median split at the last case's end: case runs (with their queueing) | rubric, figures, check
            "cold_cases_s": median(cold_cases), "cold_grading_s": median(cold_grading)}
