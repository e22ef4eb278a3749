"""Wall time per case by execution path, measured side by side in one run (medians over repeats and ratios)."""

from __future__ import annotations

import statistics
import time
from collections.abc import Callable
from pathlib import Path

from rubric import get_case
from worker import WarmCaseProcess, run_case

# isolated: a new process per case; warm: one long-lived process, a new scene per case; reused: one long-lived
# process resetting a scene built for the same structure. Batched environments are off (tools/batched_envs_check.py).
MODES = ("isolated", "warm", "reused")


class BenchFailure(RuntimeError):
    """A case failed during the benchmark: its figures would mean nothing."""


def bench_cases(case_names: list[str], repeats: int, out_dir: Path, log: Callable[[str], None] = print) -> dict:
    """Time each case in every mode, interleaved so machine noise hits all alike. Returns the figures as a dict."""
    specs = [get_case(name) for name in case_names]
    wall = {(s.name, m): [] for s in specs for m in MODES}
    steps = {s.name: [] for s in specs}
    with WarmCaseProcess() as warm, WarmCaseProcess(reuse_scenes=True) as reusing:
        # A warm process's first case pays import + init + kernel loading; time it separately, not as a case. The
        # reusing process also builds each structure once here, so every timed run of it is a reused scene.
        started = time.perf_counter()
        first = warm.run(specs[0], out_dir / "warmup")
        startup_s = time.perf_counter() - started
        log(f"warm case process start-up (first case {specs[0].name}): {startup_s:.2f} s")
        for spec in specs:
            built = reusing.run(spec, out_dir / "warmup-reused" / spec.name)
            if not built.ok:
                raise BenchFailure(f"warm-up of {spec.name} failed: {built.error}")
        if not first.ok:
            raise BenchFailure(f"warm-up failed: {first.error}")
        processes = {"warm": warm, "reused": reusing}
        for r in range(repeats):
            for spec in specs:
                for mode in MODES:
                    kwargs = {"warm_process": processes[mode]} if mode in processes else {}
                    result = run_case(spec, out_dir / f"{mode}-{r}" / spec.name,
                                      mode="isolated" if mode == "isolated" else "warm", **kwargs)
                    if not result.ok:
                        raise BenchFailure(f"{spec.name} ({mode}) failed: {result.error}")
                    if mode == "reused" and result.provenance.scene != "reused":
                        raise BenchFailure(f"{spec.name}: expected a reused scene, got {result.provenance.scene}")
                    wall[(spec.name, mode)].append(result.wall_s)
                    if mode == "reused":
                        steps[spec.name].append(result.provenance.timings.steps_s)
                    log(f"  repeat {r + 1}/{repeats} {spec.name:4s} {mode:8s} {result.wall_s:7.2f} s")
    per_case = {
        s.name: {
            **{f"{m}_s": statistics.median(wall[(s.name, m)]) for m in MODES},
            "stepping_s": statistics.median(steps[s.name]),
        }
        for s in specs
    }
    for row in per_case.values():
        row["isolated_over_warm"] = row["isolated_s"] / row["warm_s"]
        row["warm_over_reused"] = row["warm_s"] / row["reused_s"]
        row["reused_over_stepping"] = row["reused_s"] / row["stepping_s"]
    return {"repeats": repeats, "warm_startup_s": startup_s, "per_case": per_case,
            "batched": "off: arrays differ from a fresh scene (tools/batched_envs_check.py)"}


def format_cases(figures: dict) -> list[str]:
    """The per-case table, one line per case and a total."""
    per_case = figures["per_case"]
    lines = [f"median wall time per case over {figures['repeats']} repeats (s); batched: {figures['batched']}",
             f"{'case':20s} {'isolated':>9s} {'warm':>7s} {'reused':>7s} {'stepping':>9s} "
             f"{'iso/warm':>9s} {'warm/reused':>12s} {'reused/stepping':>16s}"]
    for name, row in per_case.items():
        lines.append(f"{name:20s} {row['isolated_s']:9.3f} {row['warm_s']:7.3f} {row['reused_s']:7.3f} "
                     f"{row['stepping_s']:9.3f} {row['isolated_over_warm']:8.1f}x {row['warm_over_reused']:11.1f}x "
                     f"{row['reused_over_stepping']:15.2f}x")
    totals = {m: sum(row[f"{m}_s"] for row in per_case.values()) for m in (*MODES, "stepping")}
    lines.append(f"{'all':20s} {totals['isolated']:9.3f} {totals['warm']:7.3f} {totals['reused']:7.3f} "
                 f"{totals['stepping']:9.3f} {totals['isolated'] / totals['warm']:8.1f}x "
                 f"{totals['warm'] / totals['reused']:11.1f}x {totals['reused'] / totals['stepping']:15.2f}x")
    return lines
