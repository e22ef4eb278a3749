"""Wall time per case by execution path, measured side by side in one run (medians over repeats and ratios)."""

from __future__ import annotations

import statistics
import time
from collections.abc import Callable
from pathlib import Path

from rubric import get_case

MODES = ("isolated", "warm")


class BenchFailure(RuntimeError):
    """A case failed during the benchmark: its figures would mean nothing."""


def bench_cases(case_names: list[str], repeats: int, out_dir: Path, log: Callable[[str], None] = print) -> dict:
    """Time each case in every mode, interleaved so machine noise hits all alike. Returns the figures as a dict."""
    from worker import WarmCaseProcess, run_case

    specs = [get_case(name) for name in case_names]
    wall = {(s.name, m): [] for s in specs for m in MODES}
    steps = {s.name: [] for s in specs}
    with WarmCaseProcess() as warm:
        # The warm process's first case pays import + init + kernel loading; time it separately, not as a case.
        started = time.perf_counter()
        first = warm.run(specs[0], out_dir / "warmup")
        startup_s = time.perf_counter() - started
        log(f"warm case process start-up (first case {specs[0].name}): {startup_s:.2f} s")
        if not first.ok:
            raise BenchFailure(f"warm-up failed: {first.error}")
        for r in range(repeats):
            for spec in specs:
                for mode in MODES:
                    kwargs = {"warm_process": warm} if mode == "warm" else {}
                    result = run_case(spec, out_dir / f"{mode}-{r}" / spec.name, mode=mode, **kwargs)
                    if not result.ok:
                        raise BenchFailure(f"{spec.name} ({mode}) failed: {result.error}")
                    wall[(spec.name, mode)].append(result.wall_s)
                    if mode == "warm":
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
    return {"repeats": repeats, "warm_startup_s": startup_s, "per_case": per_case}


def format_cases(figures: dict) -> list[str]:
    """The per-case table, one line per case and a total."""
    per_case = figures["per_case"]
    lines = [f"median wall time per case over {figures['repeats']} repeats (s):",
             f"{'case':6s} {'isolated':>9s} {'warm':>7s} {'ratio':>7s} {'stepping':>9s}"]
    for name, row in per_case.items():
        lines.append(f"{name:6s} {row['isolated_s']:9.2f} {row['warm_s']:7.2f} {row['isolated_over_warm']:6.1f}x "
                     f"{row['stepping_s']:9.3f}")
    total_iso = sum(row["isolated_s"] for row in per_case.values())
    total_warm = sum(row["warm_s"] for row in per_case.values())
    lines.append(f"{'all':6s} {total_iso:9.2f} {total_warm:7.2f} {total_iso / total_warm:6.1f}x")
    return lines
