"""A class at the deadline: many students submit at once, sharing the baseline cases, with a bounded set of
distinct modified configs and some configs that break the one-factor rule; timed from the first POST to the last
stored grade on one CPU worker."""

from __future__ import annotations

import copy
import json
import time
from collections.abc import Callable
from datetime import UTC, datetime

from sqlalchemy import func, select
from sqlalchemy.orm import Session

from grader.core.models import Grade, Submission
from grader.core.settings import settings
from worker.warm_gate import OPENED

from tools.bench.cases import BenchFailure
from tools.harness.processes import WARM_UP_LIMIT_S
from tools.bench.submission import WAIT_LIMIT_S, reference_sheet

# 20 table frictions (the lesson's 0.50 left out) and 20 extensions (dt, substeps) over the lesson's 1.5 s: 40
# distinct modified configs, each a one-factor change of its baseline.
TABLE_FRICTIONS = (0.05, 0.1, 0.15, 0.2, 0.25, 0.3, 0.35, 0.4, 0.45, 0.55, 0.6, 0.65, 0.7, 0.75, 0.85, 0.9, 0.95,
                   1.0, 1.1, 1.2)
EXTENSIONS = tuple((dt, substeps) for dt, options in ((0.01, (3, 4, 5, 6)), (0.02, (3, 4, 5, 6)),
                                                      (0.015, (1, 2, 3, 4)), (0.025, (1, 2, 3, 4)),
                                                      (0.03, (1, 2, 3, 4))) for substeps in options)
TWO_FACTOR_EVERY = 10  # 10% of the class


def class_sheets(students: list[str]) -> list[dict]:
    """One sheet per student: the reference answers, a table friction and an extension from the pools above, and
    every TWO_FACTOR_EVERY-th table exercise also moving the table (two factors: not run, graded as a violation)."""
    base = reference_sheet()
    sheets = []
    for i, student in enumerate(students):
        sheet = copy.deepcopy(base) | {"student": student}
        table = sheet["configs"]["table_exercise"]
        # Shifted by one each round of 20, so the two-factor sheets do not always take the same two frictions.
        table["table"]["friction"] = TABLE_FRICTIONS[(i + i // len(TABLE_FRICTIONS)) % len(TABLE_FRICTIONS)]
        table["name"] = f"table-{table['table']['friction']:.2f}"
        if i % TWO_FACTOR_EVERY == TWO_FACTOR_EVERY - 1:
            table["table"]["pos"] = [0.8, 0.0, 0.75]
        dt, substeps = EXTENSIONS[(i * 7) % len(EXTENSIONS)]
        sheet["configs"]["extension"] |= {"name": f"X-{dt}-{substeps}", "dt": dt, "substeps": substeps}
        sheets.append(sheet)
    return sheets


def distinct_configs(sheets: list[dict]) -> int:
    """How many distinct modified configs (one-factor ones) the sheets carry."""
    seen = set()
    for sheet in sheets:
        table = sheet["configs"]["table_exercise"]["table"]
        if table["pos"] == [0.8, 0.0, 0.7]:
            seen.add(("table", table["friction"]))
        extension = sheet["configs"]["extension"]
        seen.add(("extension", json.dumps([extension["dt"], extension["substeps"]])))
    return len(seen)


def _finished(engine) -> tuple[int, int, int, datetime | None, datetime | None]:
    """(graded, failed, grades whose lab check is still being evaluated, last grade stored, last grade completed)."""
    with Session(engine) as session:
        rows = dict(session.execute(select(Submission.status, func.count()).group_by(Submission.status)).all())
        last = session.scalar(select(func.max(Submission.graded_at)))
        completing = session.scalar(select(func.count()).select_from(Grade).where(Grade.completed_at.is_(None)))
        completed = session.scalar(select(func.max(Grade.completed_at)))
    return rows.get("graded", 0), rows.get("failed", 0), completing, last, completed


WARM_LIMIT_S = WARM_UP_LIMIT_S  # tools.harness.processes: a warm-up of two slots took 305 s on a loaded host


def wait_until_warm(stack, log: Callable[[str], None] = print) -> float | None:
    """Wait until the worker's case slots have warmed up (settings.warm_up_backend) and it consumes its case queues:
    its line in the worker's log (worker.warm_gate).
    A deadline finds workers that have been up for a while; the class is timed from there. Returns the seconds
    waited (None: warm-up off)."""
    if settings.warm_up_backend == "off":  # the stack's worker inherits this environment: nothing to wait for
        log("  warm-up off (WARM_UP_BACKEND=off): the case process starts on the first case")
        return None
    worker_log = stack.data_dir / "worker.log"
    started = time.monotonic()
    while time.monotonic() - started < WARM_LIMIT_S:
        if stack.worker.poll() is not None:
            raise BenchFailure(f"the worker exited ({stack.worker.returncode}) before its case process warmed up")
        done = [line for line in worker_log.read_text(errors="replace").splitlines() if OPENED in line]
        if done:
            waited = time.monotonic() - started
            log(f"  {done[0].strip()}; {waited:.1f} s after the stack was ready")
            return waited
        time.sleep(0.2)
    raise BenchFailure(f"the worker's case process did not warm up within {WARM_LIMIT_S} s (see {worker_log})")


def bench_class(stack, size: int, log: Callable[[str], None] = print) -> dict:
    """Every student of the stack's course (size of them) submits once, back to back, once the worker's case process
    has warmed up; wait for every grade and its lab check. The class's time is to the last stored grade;
    `complete_s` to the last report complete."""
    warm_s = wait_until_warm(stack, log)
    sheets = class_sheets(stack.students[:size])
    started_at = datetime.now(UTC).replace(tzinfo=None)
    started = time.monotonic()
    for i, sheet in enumerate(sheets):
        stack.client(sheet["student"]).submit(sheet)
        if (i + 1) % 20 == 0:
            log(f"  posted {i + 1}/{size} ({time.monotonic() - started:.1f} s)")
    posted_s = time.monotonic() - started
    deadline = started + WAIT_LIMIT_S * max(1, size // 20)
    while True:
        graded, failed, completing, last, completed = _finished(stack.engine)
        if graded + failed >= size and not completing:
            break
        if stack.worker.poll() is not None:
            raise BenchFailure(f"class of {size}: the worker exited ({stack.worker.returncode}) with {graded} graded")
        if time.monotonic() > deadline:
            raise BenchFailure(f"class of {size}: {graded} graded, {failed} failed when the wait limit passed")
        log(f"  {graded} graded ({completing} completing), {failed} failed ({time.monotonic() - started:.0f} s)")
        time.sleep(5 if size > 50 else 2)
    total_s = (last - started_at).total_seconds()
    two_factor = sum(1 for i in range(size) if i % TWO_FACTOR_EVERY == TWO_FACTOR_EVERY - 1)
    return {"stack": stack.kind, "submissions": size, "graded": graded, "failed": failed, "warm_up_wait_s": warm_s,
            "distinct_configs": distinct_configs(sheets), "two_factor": two_factor, "posting_s": posted_s,
            "total_s": total_s, "per_submission_s": total_s / size,
            "complete_s": (completed - started_at).total_seconds() if completed else None}
