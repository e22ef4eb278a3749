"""A class at the deadline: many students submit at once, sharing the baseline cases, with a bounded set of
distinct modified configs and some configs that break the one-factor rule; timed from the first POST to the last
stored grade, on one CPU worker or several (issue 35 item 4), every POST accounted for, and where the time went."""

from __future__ import annotations

import copy
import json
import os
import re
import time
from collections import defaultdict
from collections.abc import Callable
from datetime import UTC, datetime
from pathlib import Path

import redis
from sqlalchemy import func, select
from sqlalchemy.orm import Session

from grader.core.lifecycle import FINISHED_WHEN_MEASURED
from grader.core.models import CaseRun, Event, Grade, Submission
from grader.core.settings import settings
from worker.warm_gate import OPENED

from tools.bench.cases import BenchFailure
from tools.harness.processes import WARM_UP_LIMIT_S, children
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


def slots_per_worker(workers: int, cores: int | None = None) -> int:
    """Case slots for each of `workers` CPU workers on this host: one case process per core in all (a case steps on
    one thread, docs/benchmark.md), so one worker has a slot per core and two workers split the cores; no count of
    workers oversubscribes them (at least one slot each) and every count has the same case capacity."""
    cores = cores or len(os.sched_getaffinity(0))
    return max(1, cores // workers)


WARM_LIMIT_S = WARM_UP_LIMIT_S  # tools.harness.processes: a warm-up of two slots took 305 s on a loaded host
# No run finished and no grade, failure or lab check stored for this long: the rest of the class is counted lost
# (never a claim about speed: anything stored resets it).
STALL_LIMIT_S = 300
QUEUE_SAMPLE_S = 0.5
TASK_LINE = re.compile(r"Task worker\.tasks\.(\w+)\[[^\]]*\] succeeded in ([0-9.eE+-]+)s")


def _workers(stack) -> list:
    return list(getattr(stack, "workers", None) or [stack.worker])


def _worker_log(stack, index: int) -> Path:
    return stack.worker_log(index) if hasattr(stack, "worker_log") else stack.data_dir / "worker.log"


def _check_workers(stack, what: str) -> None:
    for index, proc in enumerate(_workers(stack)):
        if proc.poll() is not None:
            raise BenchFailure(f"worker {index + 1} exited ({proc.returncode}) {what} (see {_worker_log(stack, index)})")


def wait_until_warm(stack, log: Callable[[str], None] = print) -> float | None:
    """Wait until every worker's case slots have warmed up (settings.warm_up_backend) and it consumes its case queues:
    its line in the worker's log (worker.warm_gate).
    A deadline finds workers that have been up for a while; the class is timed from there. Returns the seconds
    waited for the last of them (None: warm-up off)."""
    if settings.warm_up_backend == "off":  # the stack's workers inherit this environment: nothing to wait for
        log("  warm-up off (WARM_UP_BACKEND=off): the case process starts on the first case")
        return None
    started = time.monotonic()
    waiting = set(range(len(_workers(stack))))
    waited = 0.0
    while waiting:
        _check_workers(stack, "before its case slots warmed up")
        for index in sorted(waiting):
            path = _worker_log(stack, index)
            done = [line for line in path.read_text(errors="replace").splitlines() if OPENED in line] \
                if path.exists() else []
            if done:
                waited = time.monotonic() - started
                log(f"  worker {index + 1}: {done[0].strip()}; {waited:.1f} s after the stack was ready")
                waiting.discard(index)
        if not waiting:
            break
        if time.monotonic() - started > WARM_LIMIT_S:
            raise BenchFailure(f"worker(s) {', '.join(str(i + 1) for i in sorted(waiting))}: case slots not warm "
                               f"within {WARM_LIMIT_S} s (see {stack.data_dir})")
        time.sleep(0.2)
    return waited


class QueueWatch:
    """Samples the broker's queues (Redis: one list per priority, kombu's `queue\\x06\\x16N`) every QUEUE_SAMPLE_S
    while the class runs: case runs (cpu), lab checks (cpu at COMPLETE_PRIORITY) and grades (grade) waiting."""

    SEP = "\x06\x16"

    def __init__(self, broker_url: str, started: float):
        self.client = redis.Redis.from_url(broker_url) if broker_url.startswith("redis") else None
        self.started = started
        self.samples: list[tuple[float, int, int, int]] = []  # (s after the first POST, runs, lab checks, grades)
        self._stop = None
        self._thread = None

    def _names(self, queue: str) -> list[str]:
        return [queue] + [f"{queue}{self.SEP}{p}" for p in range(1, 10)]

    def sample(self) -> None:
        from grader.core.lifecycle import COMPLETE_PRIORITY

        pipe = self.client.pipeline()
        for name in (*self._names("cpu"), *self._names("grade")):
            pipe.llen(name)
        lengths = pipe.execute()
        cpu, grade = lengths[:10], lengths[10:]
        checks = cpu[COMPLETE_PRIORITY]
        self.samples.append((time.monotonic() - self.started, sum(cpu) - checks, checks, sum(grade)))

    def __enter__(self):
        import threading

        if self.client is None:
            return self
        self._stop = threading.Event()

        def loop():
            while not self._stop.is_set():
                try:
                    self.sample()
                except redis.RedisError:
                    pass  # a missed sample; the class goes on
                self._stop.wait(QUEUE_SAMPLE_S)

        self._thread = threading.Thread(target=loop, daemon=True)
        self._thread.start()
        return self

    def __exit__(self, *exc):
        if self._thread is not None:
            self._stop.set()
            self._thread.join()
            self.client.close()

    def summary(self) -> dict | None:
        """Peak waiting per kind, and when the case runs' queue was last non-empty (s after the first POST)."""
        if not self.samples:
            return None
        runs = [s for s in self.samples if s[1]]
        return {"samples": len(self.samples), "runs_peak": max(s[1] for s in self.samples),
                "checks_peak": max(s[2] for s in self.samples), "grades_peak": max(s[3] for s in self.samples),
                "runs_last_waiting_s": runs[-1][0] if runs else None}


def _post_all(stack, sheets: list[dict], started: float, log: Callable[[str], None]) -> tuple[list[int], list[str]]:
    """POST every sheet back to back: (ids of the submissions answered 2xx, what each refused POST said)."""
    ids, refused = [], []
    for i, sheet in enumerate(sheets):
        try:
            ids.append(stack.client(sheet["student"]).submit(sheet)["id"])
        except Exception as exc:  # noqa: BLE001 - an HTTP error or a dropped connection: counted, never fatal
            refused.append(f"{sheet['student']}: {str(exc).splitlines()[0][:200]}")
        if (i + 1) % 20 == 0:
            log(f"  posted {i + 1}/{len(sheets)} ({time.monotonic() - started:.1f} s)")
    return ids, refused


def _states(engine, ids: list[int]) -> tuple[dict[int, str], int, datetime | None, datetime | None, int]:
    """Of the posted submissions: each one's status, how many grades are still having their lab check evaluated,
    the last grade stored, the last lab check stored, and how many of their runs have finished."""
    with Session(engine) as session:
        status = dict(session.execute(select(Submission.id, Submission.status).where(Submission.id.in_(ids))).all())
        runs_done = session.scalar(select(func.count()).select_from(CaseRun).where(
            CaseRun.submission_id.in_(ids), CaseRun.status.in_(("done", "failed"))))
        last = session.scalar(select(func.max(Submission.graded_at)).where(Submission.id.in_(ids)))
        grades = select(Grade).where(Grade.submission_id.in_(ids), Grade.superseded_at.is_(None)).subquery()
        completing = session.scalar(select(func.count()).select_from(grades).where(grades.c.completed_at.is_(None)))
        completed = session.scalar(select(func.max(grades.c.completed_at)))
    return status, completing, last, completed, runs_done


def _seconds(at: datetime | None, since: datetime) -> float | None:
    return (at - since).total_seconds() if at is not None else None


def _runs_profile(engine, ids: list[int], since: datetime, pids: dict[int, int]) -> dict:
    """The posted submissions' grading runs: reused at admission, reused in a worker, measured (and measured more than
    once), their case-process seconds, per worker; and how long the grades waited after the last run."""
    with Session(engine) as session:
        runs = session.execute(select(CaseRun.id, CaseRun.reused_from_id, CaseRun.started_at, CaseRun.finished_at,
                                      CaseRun.wall_s, CaseRun.content_key, CaseRun.worker_pid, CaseRun.status,
                                      CaseRun.name, CaseRun.provenance)
                               .where(CaseRun.submission_id.in_(ids), CaseRun.purpose == "grading")).all()
        fanned = set(session.scalars(select(Event.case_run_id).where(  # the runs finish_alike finished
            Event.submission_id.in_(ids), Event.detail.like(f"%{FINISHED_WHEN_MEASURED}"))))
        waits = session.execute(select(Submission.grading_at, Submission.graded_at)
                                .where(Submission.id.in_(ids), Submission.graded_at.is_not(None))).all()
    measured = [r for r in runs if r.reused_from_id is None and r.started_at is not None and r.wall_s is not None]
    keys = [r.content_key for r in measured]
    per_worker: dict[int, dict] = defaultdict(lambda: {"measured": 0, "case_s": 0.0, "reused": 0})
    for r in runs:
        if r.started_at is None:
            continue
        w = per_worker[pids.get(r.worker_pid, 0)]
        if r.reused_from_id is None and r.wall_s is not None:
            w["measured"] += 1
            w["case_s"] += r.wall_s
        else:
            w["reused"] += 1
    by_case: dict[str, dict] = {}
    for r in measured:  # the case process's wall time: its scene's build (a new structure), stepping, the rest
        timings, c = (r.provenance or {}).get("timings") or {}, by_case.setdefault(r.name, dict.fromkeys(
            ("measured", "fresh_scenes", "wall_s", "build_s", "steps_s"), 0))
        c["measured"] += 1
        c["fresh_scenes"] += (r.provenance or {}).get("scene") == "fresh"
        c["wall_s"] += r.wall_s
        c["build_s"] += timings.get("build_s", 0.0)
        c["steps_s"] += timings.get("steps_s", 0.0)
    grade_waits = sorted((b - a).total_seconds() for a, b in waits if a is not None)
    finished = [r.finished_at for r in measured if r.finished_at is not None]
    return {"runs": len(runs),
            "reused_at_admission": sum(1 for r in runs if r.reused_from_id is not None and r.started_at is None
                                       and r.id not in fanned),
            "finished_when_measured": sum(1 for r in runs if r.id in fanned),
            "reused_in_worker": sum(1 for r in runs if r.reused_from_id is not None and r.started_at is not None),
            "measured": len(measured), "measured_keys": len(set(keys)), "measured_twice": len(keys) - len(set(keys)),
            "failed_runs": sum(1 for r in runs if r.status == "failed"),
            "case_s": sum(r.wall_s for r in measured),
            "first_measured_s": _seconds(min((r.started_at for r in measured), default=None), since),
            "last_measured_s": _seconds(max(finished, default=None), since),
            "grading_wait_median_s": grade_waits[len(grade_waits) // 2] if grade_waits else None,
            "grading_wait_max_s": grade_waits[-1] if grade_waits else None,
            "per_worker": {str(k): v for k, v in sorted(per_worker.items())},
            "by_case": dict(sorted(by_case.items(), key=lambda kv: -kv[1]["wall_s"]))}


def _tasks_profile(stack) -> list[dict]:
    """Per worker, from its log (Celery's `Task ... succeeded in Xs`): how many tasks of each kind ran and their
    busy seconds; every task in that log is the class's (its stack runs nothing else)."""
    out = []
    for index in range(len(_workers(stack))):
        path = _worker_log(stack, index)
        tasks: dict[str, dict] = {}
        for name, seconds in TASK_LINE.findall(path.read_text(errors="replace") if path.exists() else ""):
            t = tasks.setdefault(name, {"count": 0, "busy_s": 0.0})
            t["count"] += 1
            t["busy_s"] += float(seconds)
        out.append(tasks)
    return out


def _pool_pids(stack) -> dict[int, int]:
    """Each worker's pool process ids -> that worker's number (1, 2...): which worker claimed a run."""
    return {pid: index + 1 for index, proc in enumerate(_workers(stack)) for pid in children(proc.pid)}


def bench_class(stack, size: int, log: Callable[[str], None] = print, *, slots: int | None = None) -> dict:
    """Every student of the stack's course (size of them) submits once, back to back, once every worker's case slots
    have warmed up; wait for every grade and its lab check. The class's time is to the last stored grade;
    `complete_s` to the last report complete. Every POST is accounted for: answered 2xx and ending graded or failed,
    refused, or lost (answered 2xx, yet neither graded nor failed when the wait ended). With it, where the time went:
    the runs measured and reused, each worker's tasks, the broker's queues."""
    workers = _workers(stack)
    warm_s = wait_until_warm(stack, log)
    pids = _pool_pids(stack)  # before the class: a pool process replaced later counts as no worker's (0)
    sheets = class_sheets(stack.students[:size])
    started_at = datetime.now(UTC).replace(tzinfo=None)
    started = time.monotonic()
    with QueueWatch(stack.env.get("BROKER_URL", ""), started) as queues:
        ids, refused = _post_all(stack, sheets, started, log)
        posted_s = time.monotonic() - started
        deadline = started + WAIT_LIMIT_S * max(1, size // 20)
        progress, progressed = None, time.monotonic()
        while True:
            status, completing, last, completed, runs_done = _states(stack.engine, ids)
            graded = sum(1 for s in status.values() if s == "graded")
            failed = sum(1 for s in status.values() if s == "failed")
            if graded + failed >= len(ids) and not completing:
                break
            _check_workers(stack, f"with {graded} of {len(ids)} graded")
            if (graded, failed, completing, runs_done) != progress:
                progress, progressed = (graded, failed, completing, runs_done), time.monotonic()
            if time.monotonic() > deadline or time.monotonic() - progressed > STALL_LIMIT_S:
                log(f"  stopped waiting: {graded} graded, {failed} failed, {completing} completing, {runs_done} runs "
                    f"finished; nothing stored for {time.monotonic() - progressed:.0f} s")
                break
            log(f"  {graded} graded ({completing} completing), {failed} failed ({time.monotonic() - started:.0f} s)")
            time.sleep(5 if size > 50 else 1)
    lost = sorted(i for i in ids if status.get(i) not in ("graded", "failed"))
    if lost:
        log(f"  LOST: {len(lost)} submission(s) answered 2xx and neither graded nor failed: {lost[:20]}")
    for line in refused[:5]:
        log(f"  refused: {line}")
    total_s = _seconds(last, started_at) if last is not None else float("nan")
    two_factor = sum(1 for i in range(size) if i % TWO_FACTOR_EVERY == TWO_FACTOR_EVERY - 1)
    return {"stack": stack.kind, "workers": len(workers), "slots": slots, "submissions": size,
            "accepted": len(ids), "refused": len(refused), "refused_examples": refused[:5],
            "graded": graded, "failed": failed, "lost": len(lost), "lost_ids": lost[:50],
            "warm_up_wait_s": warm_s, "distinct_configs": distinct_configs(sheets), "two_factor": two_factor,
            "posting_s": posted_s, "total_s": total_s, "per_submission_s": total_s / size,
            "complete_s": _seconds(completed, started_at),
            "profile": {"runs": _runs_profile(stack.engine, ids, started_at, pids), "tasks": _tasks_profile(stack),
                        "queues": queues.summary()}}
