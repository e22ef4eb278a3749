"""Case slots and warm-up (issue 35), measured side by side in one run: how much of a core one case process uses
while it steps; a cold reference submission on a worker with one case slot and with one per core; the first
submission after a worker's start (once it is warm) against the cold ones after it; how long each warm-up took."""

from __future__ import annotations

import os
import re
import threading
import time
from collections.abc import Callable
from pathlib import Path

import psutil

from rubric import get_case
from tools.bench.cases import BenchFailure
from tools.harness.stack import service_stack
from tools.bench.stats import median
from tools.bench.submission import reference_sheet, time_submission
from worker import WarmCaseProcess

CPU_CASES = ("N1", "N2", "N3", "N4")
SAMPLE_S = 0.01


def _sampled(process: psutil.Process, run: Callable[[], object]) -> tuple[object, float, dict[int, float]]:
    """Run `run()` while sampling the process's CPU times; (its result, wall s, CPU s per thread id)."""
    first: dict[int, float] = {}
    last: dict[int, float] = {}
    stop = threading.Event()

    def sample() -> None:
        while not stop.is_set():
            with_threads = {t.id: t.user_time + t.system_time for t in process.threads()}
            for tid, cpu in with_threads.items():
                first.setdefault(tid, cpu)
            last.update(with_threads)
            stop.wait(SAMPLE_S)

    sampler = threading.Thread(target=sample, daemon=True)
    started = time.perf_counter()
    sampler.start()
    result = run()
    stop.set()
    sampler.join()
    return result, time.perf_counter() - started, {tid: last[tid] - first.get(tid, 0.0) for tid in last}


def case_cpu(out_dir: Path, repeats: int, log: Callable[[str], None] = print) -> dict:
    """CPU seconds per wall second of one warm case process over each case (reused scene: stepping dominates), and
    how that CPU time spreads over its threads: one busy thread means one case uses at most one core."""
    per_wall, busiest_share, busy_threads, steps_share = [], [], [], []
    with WarmCaseProcess(reuse_scenes=True) as warm:
        for name in CPU_CASES:  # import, kernels, and each structure's scene: not what is measured
            if not (result := warm.run(get_case(name), out_dir / "warm-up" / name)).ok:
                raise BenchFailure(f"{name} failed warming up: {result.error}")
        process = psutil.Process(warm.pid)
        for r in range(repeats):
            for name in CPU_CASES:
                result, wall, threads = _sampled(process, lambda: warm.run(get_case(name), out_dir / f"{r}" / name))
                if not result.ok:
                    raise BenchFailure(f"{name} failed: {result.error}")
                cpu = sum(threads.values())
                per_wall.append(cpu / wall)
                busiest_share.append(max(threads.values()) / cpu if cpu else 0.0)
                busy_threads.append(sum(1 for t in threads.values() if cpu and t > 0.05 * cpu))
                steps_share.append(result.provenance.timings.steps_s / wall)
                log(f"  {name} repeat {r + 1}: {cpu:.2f} CPU s over {wall:.2f} s wall ({cpu / wall:.2f} cores), "
                    f"busiest thread {busiest_share[-1]:.0%} of it, stepping {steps_share[-1]:.0%} of the wall time")
    return {"cases": list(CPU_CASES), "repeats": repeats, "cpu_per_wall": median(per_wall),
            "cpu_per_wall_max": max(per_wall), "busiest_thread_share": median(busiest_share),
            "busy_threads_max": max(busy_threads), "stepping_share": median(steps_share)}


def _warm_up_s(log_path: Path) -> float | None:
    found = re.findall(r"case slots warm after ([0-9.]+) s", log_path.read_text(errors="replace"))
    return float(found[-1]) if found else None


def bench_slots(folder: Path, repeats: int, log: Callable[[str], None] = print) -> dict:
    """Per slot count (1, then one per core): the worker's warm-up, the first submission once warm (a fresh
    database: every case measured), then `repeats` cold ones (force_rerun)."""
    cores = len(os.sched_getaffinity(0))
    rows = []
    for slots in sorted({1, max(2, cores)}):
        log(f"== a worker with {slots} case slot(s): warm-up, first submission once warm, {repeats} cold")
        with service_stack("embedded", folder, worker_env={"WORKER_CONCURRENCY": str(slots)}, warm=True) as stack:
            warm_up_s = _warm_up_s(stack.data_dir / "worker.log")
            client, staff, sheet = stack.client(stack.students[0]), stack.client("prof"), reference_sheet()
            first = time_submission(client, sheet, worker=stack.worker)
            log(f"  warm-up {warm_up_s:.1f} s; first submission once warm {first.graded_s:.2f} s")
            cold = []
            for r in range(repeats):
                cold.append(time_submission(staff, sheet, worker=stack.worker, force_rerun=True).graded_s)
                log(f"  cold {r + 1}/{repeats}: {cold[-1]:.2f} s")
        rows.append({"slots": slots, "warm_up_s": warm_up_s, "first_s": first.graded_s, "cold_s": median(cold),
                     "cold_samples_s": cold, "case_runs": first.state["progress"]["total"],
                     "first_over_cold": first.graded_s / median(cold)})
    return {"cores": cores, "repeats": repeats, "rows": rows}


def run_slots(out_dir: Path, repeats: int, log: Callable[[str], None]) -> dict:
    log("== one case process's CPU use while it steps (warm, reused scenes)")
    figures = {"case_cpu": case_cpu(out_dir / "case-cpu", repeats, log=log)}
    figures |= bench_slots(out_dir / "services", repeats, log=log)
    return figures


def format_slots(f: dict, verdict: Callable[..., str]) -> list[str]:
    cpu = f["case_cpu"]
    lines = [f"one case process while it steps ({', '.join(cpu['cases'])}, {cpu['repeats']} repeats, warm, reused "
             f"scenes): {cpu['cpu_per_wall']:.2f} CPU s per wall s (max {cpu['cpu_per_wall_max']:.2f}), its busiest "
             f"thread {cpu['busiest_thread_share']:.0%} of that, at most {cpu['busy_threads_max']} busy thread(s), "
             f"stepping {cpu['stepping_share']:.0%} of the wall time; the host has {f['cores']} cores",
             f"a cold reference submission (force_rerun), POST to stored grade, embedded, median of {f['repeats']}:",
             f"  {'slots':>5s} {'warm-up':>8s} {'first once warm':>16s} {'cold':>7s} {'first/cold':>11s}"]
    for row in f["rows"]:
        lines.append(f"  {row['slots']:5d} {row['warm_up_s']:7.1f}s {row['first_s']:15.2f}s {row['cold_s']:6.2f}s "
                     f"{row['first_over_cold']:10.2f}x")
    many = f["rows"][-1]
    one = f["rows"][0]
    lines += [f"  cold with {many['slots']} slots: {many['cold_s']:.2f} s ({one['cold_s'] / many['cold_s']:.2f}x "
              f"faster than 1 slot)   {verdict('slots_cold_s', many['cold_s'])}",
              f"  first submission after start, once warm: {many['first_over_cold']:.2f}x a warm cold one   "
              f"{verdict('first_over_cold', many['first_over_cold'])}"]
    return lines

