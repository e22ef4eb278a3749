"""One full L03 submission timed from HTTP POST to its stored grade: first on a just-started worker, cold (every
case measured again, force_rerun) and fully reused (every case run reuses a stored measurement). The worker adds
the lab check after storing the grade; when it was stored is timed too."""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path

import yaml

from tools.bench.cases import BenchFailure
from tools.bench.stats import median

REFERENCE_SHEET = Path(__file__).resolve().parent.parent.parent / "examples" / "l03" / "reference.yaml"
# Safety stop per submission only (a cold kernel cache can take minutes).
WAIT_LIMIT_S = 900


def reference_sheet() -> dict:
    return yaml.safe_load(REFERENCE_SHEET.read_text())


def _utcnow() -> datetime:
    return datetime.now(UTC).replace(tzinfo=None)


def wait_graded(client, submission_id: int, *, poll_s: float = 0.1, worker=None) -> dict:
    """Poll until graded with its lab check stored (graded_at is not moved by it); raise BenchFailure
    on failed, past WAIT_LIMIT_S, or when `worker` (a Popen) exited."""
    deadline = time.monotonic() + WAIT_LIMIT_S
    while True:
        if worker is not None and worker.poll() is not None:
            raise BenchFailure(f"the worker exited ({worker.returncode}) with submission {submission_id} unfinished")
        state = client.submission(submission_id)
        if state["status"] == "graded" and state["report_complete"]:
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


def _event_at(events: list[dict], state: str, submission_id: int) -> datetime:
    """When the submission's last event of `state` (not a case run's) was stored."""
    found = [e for e in events if e["case_run_id"] is None and e["state"] == state]
    if not found:
        raise BenchFailure(f"submission {submission_id}: no '{state}' event among {[e['state'] for e in events]}")
    return _at(found[-1]["at"])


@dataclass
class Timed:
    """One submission timed from just before its POST (server clock): to its stored grade, and to its lab check
    stored with it (the report complete)."""

    graded_s: float
    complete_s: float
    state: dict


def grading_seconds(client, state: dict) -> float:
    """Seconds from a graded submission's last case finishing (its 'grading' event) to its stored grade: the rubric.
    The rest of its POST-to-grade time went to its case runs and their queueing."""
    return (_at(state["graded_at"]) - _event_at(client.events(state["id"]), "grading", state["id"])).total_seconds()


def time_submission(client, sheet: dict, *, worker=None, **options) -> Timed:
    """POST the sheet, wait for its grade and then for its report to be complete (so the next submission finds an
    idle worker)."""
    posted_at = _utcnow()
    created = client.submit(sheet, **options)
    state = wait_graded(client, created["id"], worker=worker)
    complete_at = _event_at(client.events(state["id"]), "lab-check", state["id"])
    return Timed(graded_after(state, posted_at), (complete_at - posted_at).total_seconds(), state)


def bench_submission(stack, repeats: int, log: Callable[[str], None] = print) -> dict:
    """First, cold and reused submissions of examples/l03/reference.yaml on one stack, cold and reused interleaved."""
    client = stack.client(stack.students[0])
    staff = stack.client("prof")  # force_rerun (the cold submissions) is a staff power
    sheet = reference_sheet()
    first = time_submission(client, sheet, worker=stack.worker)
    log(f"  submission on a just-started worker: {first.graded_s:.2f} s ({first.state['progress']['total']} case "
        f"runs)")
    cold, reused, cold_cases, cold_rubric, cold_complete, reused_complete = [], [], [], [], [], []
    for r in range(repeats):
        timed = time_submission(staff, sheet, worker=stack.worker, force_rerun=True)
        cold.append(timed.graded_s)
        cold_complete.append(timed.complete_s)
        cold_rubric.append(grading_seconds(staff, timed.state))
        cold_cases.append(timed.graded_s - cold_rubric[-1])
        log(f"  repeat {r + 1}/{repeats} cold {timed.graded_s:.2f} s (cases {cold_cases[-1]:.2f} s, "
            f"rubric {cold_rubric[-1]:.2f} s; lab check at {timed.complete_s:.2f} s)")
        timed = time_submission(client, sheet, worker=stack.worker)
        runs = client.case_runs(timed.state["id"])
        if not all(run["reused_from_id"] for run in runs):
            raise BenchFailure(f"submission {timed.state['id']}: expected every case run reused")
        reused.append(timed.graded_s)
        reused_complete.append(timed.complete_s)
        log(f"  repeat {r + 1}/{repeats} reused {timed.graded_s:.2f} s (lab check at "
            f"{timed.complete_s:.2f} s)")
    return {"stack": stack.kind, "repeats": repeats, "case_runs": timed.state["progress"]["total"],
            "first_s": first.graded_s, "cold_s": median(cold), "reused_s": median(reused), "cold_samples_s": cold,
            "reused_samples_s": reused,
            # the cold median split at the last case's end: case runs (with their queueing) | the rubric
            "cold_cases_s": median(cold_cases), "cold_rubric_s": median(cold_rubric),
            # POST to the lab check stored with the grade (evaluated after it)
            "cold_complete_s": median(cold_complete), "reused_complete_s": median(reused_complete)}
