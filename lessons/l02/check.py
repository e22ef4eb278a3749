"""The L02 lab verdict: the lifecycle's conditions, each with its measured evidence, ending in `L02 CHECK: PASSED` or
`L02 CHECK: FAILED` and the failed conditions. Tolerances are the reviewed records of its rubric, as grading's."""

from __future__ import annotations

import math
from collections.abc import Iterable

from rubric.check import Condition, LabReport, OutputLocation, check_line
from rubric.results import CaseResult, discretization_problems
from rubric.rubrics import Rubric, load_rubric

from .specs import QUERY_T_S, free_fall, touch_time

CHECK_CASES = ("S1", "S2")


def verdict_line(passed: bool, failed: Iterable[str] = ()) -> str:
    return check_line("L02", passed, failed)


class L02Report(LabReport):
    @staticmethod
    def line(passed: bool, failed: Iterable[str] = ()) -> str:
        return verdict_line(passed, failed)


def evaluate(results: dict[str, CaseResult], *, outputs: OutputLocation, rubric: Rubric | None = None,
             variant=None) -> L02Report:
    """Every condition on the runs of S1 and S2 (keyed by case name)."""
    if variant is not None:
        raise ValueError("L02 has no variant space")
    rubric = rubric or load_rubric("L02")
    tol = {name: record.value for name, record in rubric.tolerances.items()}
    ok = {name: results[name] for name in CHECK_CASES if name in results and results[name].ok}
    missing = [name for name in CHECK_CASES if name not in ok]
    conditions = [
        _ran(results, missing),
        _counts(ok),
        _duration(ok, tol["reported_time"]),
        _free_fall(ok, tol["reported_height"], tol["reported_velocity"]),
        _touch(ok, tol["touch_time_resolution"]),
        Condition(id="outputs", title="generated .npz files stay in the configured output directory, outside "
                                      "version control", passed=outputs.passed, evidence=outputs.evidence),
    ]
    return L02Report(passed=all(c.passed for c in conditions), conditions=conditions,
                     backends={name: r.backend for name, r in results.items()}, rubric_version=rubric.version)


def _ran(results, missing) -> Condition:
    lines = [f"{name}: {results[name].status}" + (f" ({results[name].error})" if results[name].error else "")
             if name in results else f"{name}: not run" for name in CHECK_CASES]
    return Condition(id="runs", title="S1 and S2 were built, stepped and observed, each with valid arrays",
                     passed=not missing, evidence="; ".join(lines))


def _counts(ok) -> Condition:
    lines, passed = [], len(ok) == len(CHECK_CASES)
    for name, result in ok.items():
        w, t = result.provenance.discretization, result.arrays.get("t")
        problems = discretization_problems(result.spec, w, t)
        passed &= not problems and w.sample_count == w.n_steps and w.internal_updates == w.n_steps * w.substeps
        lines.append(f"{name}: dt {w.dt:g} s x {w.n_steps} steps, {w.sample_count} samples, {w.substeps} substeps "
                     f"-> {w.internal_updates} internal updates at {w.substep_dt:g} s" +
                     (f"; {'; '.join(problems)}" if problems else ""))
    return Condition(id="counts", title="samples = n_steps and internal updates = n_steps x substeps, as the engine "
                                        "counted them", passed=passed, evidence="\n".join(lines) or "no run")


def _duration(ok, tolerance: float) -> Condition:
    times = {name: r.provenance.discretization.duration for name, r in ok.items()}
    passed = len(times) == len(CHECK_CASES) and max(times.values()) - min(times.values()) <= tolerance
    return Condition(id="duration", title="both runs cover the same simulated time (n_steps x dt)", passed=passed,
                     evidence=", ".join(f"{n} {s:.6g} s" for n, s in times.items()) + f" (tolerance {tolerance:g} s)")


def _free_fall(ok, height_tol: float, velocity_tol: float) -> Condition:
    z_exact, vz_exact = free_fall(QUERY_T_S)
    lines, passed = [], len(ok) == len(CHECK_CASES)
    for name, result in ok.items():
        m = result.metrics
        good = math.isclose(m.query_t, QUERY_T_S, abs_tol=1e-6) and abs(m.z_at_query - z_exact) <= height_tol \
            and abs(m.vz_at_query - vz_exact) <= velocity_tol
        passed &= good
        lines.append(f"{name}: z {m.z_at_query:.4f} m, vz {m.vz_at_query:.4f} m/s at t = {m.query_t:.4g} s")
    lines.append(f"exact free fall: z {z_exact:.4f} m, vz {vz_exact:.4f} m/s (tolerances {height_tol:g} m, "
                 f"{velocity_tol:g} m/s)")
    return Condition(id="free_fall", title=f"before touching down the box follows free fall (t = {QUERY_T_S:g} s)",
                     passed=passed, evidence="\n".join(lines))


def _touch(ok, tolerance: float) -> Condition:
    exact = touch_time()
    lines, passed = [], len(ok) == len(CHECK_CASES)
    for name, result in ok.items():
        first = result.metrics.first_contact_t
        passed &= first is not None and abs(first - exact) <= tolerance
        lines.append(f"{name}: first contact sample at " + (f"t = {first:.4g} s" if first is not None else "none"))
    lines.append(f"exact free fall touches down at {exact:.4f} s (tolerance {tolerance:g} s)")
    return Condition(id="touch", title="the box touches the ground when free fall says it should", passed=passed,
                     evidence="\n".join(lines))
