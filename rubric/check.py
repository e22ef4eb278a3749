"""The L03 lab verdict: every condition of the lesson's "How to know the lab worked", with its measured evidence.

Pure: takes case results and the caller's finding about where outputs were written, returns a CheckReport whose
text ends in `L03 CHECK: PASSED` or `L03 CHECK: FAILED` followed by the specific failed conditions. Its tolerances
are the reviewed records of the published rubric version (rubric/lessons/), the same ones grading uses, so the lab
and the grade can never judge one relationship under two different ranges.
"""

from __future__ import annotations

import math
from collections.abc import Iterable

import numpy as np
from pydantic import BaseModel

from .cases import CONTACT_CASES
from .metrics import Alignment, ContactMetrics, LaneMetrics, align
from .relations import cases_agree, lanes_by_pair, proxy_change, stop_change
from .results import FRAME_FIELDS, CaseResult, discretization_problems
from .rubrics import Rubric, load_rubric
from .specs import field_changes
from .variants import Variant
from .variants.texts import duration_condition

# The lesson's case table (dt, substeps -> substep_dt, internal updates over 1.5 s), copied from the lesson text so
# the check compares derived values against the lesson, not against the same code that derived them.
LESSON_TIMING = {
    "N1": dict(dt=0.01, substeps=1, substep_dt=0.010, samples=150, internal_updates=150),
    "N2": dict(dt=0.01, substeps=2, substep_dt=0.005, samples=150, internal_updates=300),
    "N3": dict(dt=0.02, substeps=1, substep_dt=0.020, samples=75, internal_updates=75),
    "N4": dict(dt=0.02, substeps=2, substep_dt=0.010, samples=75, internal_updates=150),
}
LESSON_DURATION_S = 1.5
BASELINE, TABLE_030 = "friction-baseline", "friction-table-0.30"


def variant_timing(variant: Variant) -> tuple[dict[str, dict], float]:
    """The case table and duration a variant's check expects, by the lesson's own arithmetic on the variant's
    parameters (dt / substeps, duration / dt), not read from the specs whose runs it checks."""
    p = variant.parameters
    grid = {"N1": ("fine_dt", "base_substeps"), "N2": ("fine_dt", "more_substeps"),
            "N3": ("coarse_dt", "base_substeps"), "N4": ("coarse_dt", "more_substeps")}
    table = {}
    for name, (dt_name, sub_name) in grid.items():
        dt, substeps = p[dt_name], p[sub_name]
        samples = round(p["duration"] / dt)
        table[name] = dict(dt=dt, substeps=substeps, substep_dt=dt / substeps, samples=samples,
                           internal_updates=samples * substeps)
    return table, p["duration"]


def check_line(lesson: str, passed: bool, failed: Iterable[str] = ()) -> str:
    """A lesson's verdict: '<LESSON> CHECK: PASSED', or '<LESSON> CHECK: FAILED', optionally naming the failed
    conditions."""
    if passed:
        return f"{lesson} CHECK: PASSED"
    failed = list(failed)
    return f"{lesson} CHECK: FAILED" + (" \u2014 " + "; ".join(failed) if failed else "")


def verdict_line(passed: bool, failed: Iterable[str] = ()) -> str:
    """L03's verdict: 'L03 CHECK: PASSED', or 'L03 CHECK: FAILED', optionally naming the failed conditions."""
    return check_line("L03", passed, failed)


class Condition(BaseModel):
    id: str
    title: str
    passed: bool
    evidence: str


class OutputLocation(BaseModel):
    """Where the caller wrote generated files; filesystem facts are gathered outside this pure module."""

    passed: bool
    evidence: str


class _Tolerances:
    """The reviewed tolerance records of one rubric version, by name."""

    def __init__(self, rubric: Rubric):
        self.rubric = rubric

    def __getitem__(self, name: str) -> float:
        return self.rubric.tolerances[name].value

    def show(self, name: str) -> str:
        t = self.rubric.tolerances[name]
        return f"{t.value:g} {t.unit}, '{name}' of rubric {self.rubric.lesson} v{self.rubric.version}"


class CheckOutcome(BaseModel):
    """What is stored with a grade: the verdict line exactly as `verdict_line` writes it, every condition with its
    evidence, the rubric version whose tolerances judged them, and the cases (with backends) it was evaluated on."""

    passed: bool
    verdict_line: str
    conditions: list[Condition]
    rubric_version: str
    backends: dict[str, str] = {}


class LabReport(BaseModel):
    """A lesson's lab check as evaluated: every condition with its evidence, the backends of the runs it read and the
    rubric version whose tolerances judged it. A lesson's report says its own verdict line (`line`)."""

    passed: bool
    conditions: list[Condition]
    backends: dict[str, str]
    rubric_version: str

    @staticmethod
    def line(passed: bool, failed: Iterable[str] = ()) -> str:
        return verdict_line(passed, failed)

    @property
    def failed(self) -> list[Condition]:
        return [c for c in self.conditions if not c.passed]

    def verdict_line(self) -> str:
        return self.line(self.passed)

    def outcome(self, notes: dict[str, str] | None = None) -> CheckOutcome:
        """The stored form. `notes` (condition id -> text) are appended to that condition's evidence: what the
        condition means where the check ran (a grading service rather than a local lab run), never a verdict."""
        notes = notes or {}
        unknown = set(notes) - {c.id for c in self.conditions}
        if unknown:
            raise KeyError(f"notes for unknown conditions: {sorted(unknown)}")
        conditions = [c.model_copy(update={"evidence": c.evidence + ("\n" + notes[c.id] if c.id in notes else "")})
                      for c in self.conditions]
        return CheckOutcome(passed=self.passed, verdict_line=self.line(self.passed, [c.title for c in self.failed]),
                            conditions=conditions, rubric_version=self.rubric_version, backends=self.backends)

    def render_text(self) -> str:
        lines = []
        for c in self.conditions:
            lines.append(f"[{'PASS' if c.passed else 'FAIL'}] {c.title}")
            lines += [f"       {line}" for line in c.evidence.splitlines()]
        lines.append("")
        lines.append(self.verdict_line())
        for c in self.failed:
            lines.append(f"  failed: {c.title}")
        return "\n".join(lines)


class CheckReport(LabReport):
    """L03's lab check: its conditions and the metrics they read."""

    contact: dict[str, ContactMetrics]
    lanes: list[LaneMetrics]
    alignment: Alignment | None


def evaluate(results: dict[str, CaseResult], *, outputs: OutputLocation, rubric: Rubric | None = None,
             variant: Variant | None = None) -> CheckReport:
    """Evaluate every lab condition on `results` (keyed by case name: N1-N4 and the two friction runs).

    Tolerances come from `rubric` (default: the latest published L03 version). Under a `variant` (a pool's variant
    checked before students see it) the timing table and duration are the variant's; every relation is the lesson's.
    """
    tol = _Tolerances(rubric or load_rubric("L03"))
    timing, duration = (LESSON_TIMING, LESSON_DURATION_S) if variant is None else variant_timing(variant)
    ok = {name: r for name, r in results.items() if r.ok}
    contact = {n: ok[n].metrics for n in CONTACT_CASES if n in ok}
    lanes = [m for name in (BASELINE, TABLE_030) if name in ok for m in ok[name].metrics.lanes.values()]
    alignment = align("N1", ok["N1"].arrays, "N4", ok["N4"].arrays) if {"N1", "N4"} <= set(ok) else None
    conditions = [
        _processes(results),
        _rendering(results),
        _arrays(results),
        _duration(results, ok, duration, duration_condition(variant)),
        _timing_table(ok, timing),
        _contact(contact, ok),
        _substeps_reduce_proxy(contact, tol),
        _n1_n4(alignment, tol),
        _multi_evidence(contact),
        _friction_baseline(lanes, ok, tol),
        _table_change(lanes, ok, tol),
        Condition(
            id="outputs",
            title="generated .npz files and figures stay in the configured output directory, outside version control",
            passed=outputs.passed,
            evidence=outputs.evidence,
        ),
    ]
    return CheckReport(
        passed=all(c.passed for c in conditions),
        conditions=conditions,
        contact=contact,
        lanes=lanes,
        alignment=alignment,
        backends={name: r.backend for name, r in results.items()},
        rubric_version=tol.rubric.version,
    )


def _missing(results: dict[str, CaseResult], names) -> list[str]:
    out = []
    for name in names:
        r = results.get(name)
        if r is None:
            out.append(f"{name}: not run")
        elif not r.ok:
            out.append(f"{name}: {r.status}: {r.error}")
    return out


def _processes(results) -> Condition:
    lines, passed = [], True
    for name, r in results.items():
        p = r.provenance
        if p is None:
            passed = False
            lines.append(f"{name}: requested {r.spec.backend}, no backend reported; {r.status}: {r.error}")
            continue
        good = r.ok and p.exit_status == 0 and p.actual_backend == p.requested_backend
        passed &= good
        lines.append(f"{name}: requested {p.requested_backend} -> actual {p.actual_backend} ({p.device_name}), "
                     f"mode {p.execution_mode}, exit {p.exit_status}{'' if r.ok else f'; {r.status}: {r.error}'}")
    return Condition(id="processes", passed=passed, evidence="\n".join(lines),
                     title="every case process reports its requested mode and actual backend and exits successfully")


def _rendering(results) -> Condition:
    lines, passed = [], True
    for name, r in results.items():
        if r.provenance is None:
            passed = False
            lines.append(f"{name}: no rendering report ({r.status})")
            continue
        rd = r.provenance.rendering
        shapes = " ".join(f"{f}={tuple(r.arrays[f].shape)}" for f in FRAME_FIELDS if f in r.arrays)
        frames_ok = all(
            (r.arrays[f].size > 0) == r.spec.render for f in FRAME_FIELDS if f in r.arrays
        ) and all(f in r.arrays for f in FRAME_FIELDS)
        good = rd.requested == r.spec.render and rd.status == ("OK" if r.spec.render else "SKIP") and frames_ok
        passed &= good
        lines.append(f"{name}: requested={'on' if rd.requested else 'off'} status={rd.status} {shapes}")
    return Condition(id="rendering", passed=passed, evidence="\n".join(lines),
                     title="every case reports its rendering mode: frames when enabled, explicit empty frames and SKIP when disabled")


def _arrays(results) -> Condition:
    lines, passed = [], True
    for name, r in results.items():
        if r.ok:
            lines.append(f"{name}: {r.spec.sample_count} samples in every array, all finite")
        else:
            passed = False
            lines.append(f"{name}: {r.status}: {r.error}")
    return Condition(id="arrays", passed=passed, evidence="\n".join(lines),
                     title="all required arrays have the expected length and contain finite values")


def _duration(results, ok, duration: float, title: str) -> Condition:
    """Read from what the engine reported (provenance) and from the sampled time axis itself, not from the spec."""
    lines, passed = _missing(results, CONTACT_CASES), not _missing(results, CONTACT_CASES)
    counts = {}
    for name in CONTACT_CASES:
        if name not in ok:
            continue
        d, t = ok[name].provenance.discretization, ok[name].arrays["t"]
        problems = discretization_problems(ok[name].spec, d, t)
        good = not problems and math.isclose(d.duration, duration, rel_tol=1e-9)
        counts[name] = len(t)
        passed &= good
        lines.append(f"{name}: engine ran {d.n_steps} outer steps x dt {d.dt:g} s = {d.duration:.4f} s; {len(t)} samples "
                     f"from t={float(t[0]):.4f} to {float(t[-1]):.4f} s" + "".join(f"; {p}" for p in problems))
    by_dt = {}
    for name, n in counts.items():
        by_dt.setdefault(ok[name].provenance.discretization.dt, set()).add(n)
    if len(by_dt) < 2 or any(len(v) != 1 for v in by_dt.values()) or len({min(v) for v in by_dt.values()}) != len(by_dt):
        passed = False
        lines.append(f"sample count does not change with dt as expected: {by_dt}")
    return Condition(id="duration", passed=passed, evidence="\n".join(lines), title=title)


def _timing_table(ok, timing: dict[str, dict]) -> Condition:
    lines, passed = [], True
    for name, expected in timing.items():
        if name not in ok:
            passed = False
            lines.append(f"{name}: no result")
            continue
        d = ok[name].provenance.discretization
        got = dict(dt=d.dt, substeps=d.substeps, substep_dt=d.substep_dt, samples=d.sample_count,
                   internal_updates=d.internal_updates)
        good = all(math.isclose(got[k], v, rel_tol=1e-9) for k, v in expected.items())
        passed &= good
        lines.append(f"{name}: engine substep_dt={d.substep_dt:g} s, internal updates={d.internal_updates}, "
                     f"samples={d.sample_count}" + ("" if good else f"  (lesson table: {expected})"))
    return Condition(id="timing_table", passed=passed, evidence="\n".join(lines),
                     title="substep_dt and internal update counts reported by the engine match the case table")


def _contact(contact: dict[str, ContactMetrics], ok) -> Condition:
    lines, passed = [], len(contact) == len(CONTACT_CASES)
    for name in CONTACT_CASES:
        m = contact.get(name)
        if m is None:
            lines.append(f"{name}: no result")
            continue
        good = m.first_contact_index is not None and not m.passed_through
        passed &= good
        first = f"first contact at t={m.first_contact_time:.2f} s" if m.first_contact_time is not None else "NO CONTACT reported"
        lines.append(f"{name}: {first}, {m.contact_samples}/{m.n_samples} samples in contact, lowest centre "
                     f"z={m.min_z:.4f} m vs table top {ok[name].spec.table.top_z:.4f} m"
                     + (" (PASSED THROUGH)" if m.passed_through else ""))
    return Condition(id="contact", passed=passed, evidence="\n".join(lines),
                     title="the cube contacts the table in every case and does not pass through it")


def _substeps_reduce_proxy(contact, tol: "_Tolerances") -> Condition:
    lines, passed = [], True
    for coarse, fine in (("N1", "N2"), ("N3", "N4")):
        if coarse not in contact or fine not in contact:
            passed = False
            lines.append(f"{coarse} vs {fine}: missing result")
            continue
        change = proxy_change(contact[coarse], contact[fine], tol["proxy_resolution"])
        passed &= change.direction == "decrease"
        lines.append(f"dt={contact[coarse].dt:g}: {change.describe()}; a decrease must exceed "
                     f"{tol.show('proxy_resolution')}")
    return Condition(id="substeps_reduce_proxy", passed=passed, evidence="\n".join(lines),
                     title="at fixed dt, the finer internal timestep reduces the penetration proxy")


def _n1_n4(alignment: Alignment | None, tol: "_Tolerances") -> Condition:
    title = "N1 and N4 agree within the reviewed tolerance at shared sample times, with different sample counts"
    if alignment is None:
        return Condition(id="n1_n4_agree", title=title, passed=False, evidence="N1 or N4 has no result")
    dz, dvz = alignment.max_abs_diff["z"], alignment.max_abs_diff["vz"]
    passed = alignment.samples_a != alignment.samples_b and cases_agree(
        alignment, dz_tol=tol["n1_n4_max_dz"], dvz_tol=tol["n1_n4_max_dvz"])
    evidence = (
        f"samples N1={alignment.samples_a}, N4={alignment.samples_b}; {alignment.shared_samples} shared times "
        f"({', '.join(f'{t:g}' for t in alignment.first_shared_times)}, ...)\n"
        f"max |z_N1 - z_N4| = {dz:.3e} m (tolerance {tol.show('n1_n4_max_dz')}); "
        f"max |vz_N1 - vz_N4| = {dvz:.3e} m/s (tolerance {tol.show('n1_n4_max_dvz')})"
    )
    return Condition(id="n1_n4_agree", title=title, passed=passed, evidence=evidence)


def _multi_evidence(contact) -> Condition:
    lines, passed = [], len(contact) == len(CONTACT_CASES)
    for name, m in contact.items():
        values = [m.penetration_proxy, m.min_clearance, m.tail_settling_error, m.tail_peak_to_peak, m.max_tilt_deg]
        good = all(np.isfinite(values)) and m.first_contact_index is not None
        passed &= good
        up = f"{m.max_upward_velocity_after_contact:.3f}" if m.max_upward_velocity_after_contact is not None else "n/a"
        lines.append(
            f"{name}: proxy {m.penetration_proxy * 1000:.2f} mm | contact {m.contact_samples} samples | "
            f"separation {m.separation_samples} samples ({m.separation_duration:.2f} s) | max upward vz {up} m/s | "
            f"tail error {m.tail_settling_error * 1000:+.3f} mm (p-p {m.tail_peak_to_peak * 1000:.3f} mm) | "
            f"tilt {m.max_tilt_deg:.2f} deg"
        )
    return Condition(id="multi_evidence", passed=passed, evidence="\n".join(lines),
                     title="the interpretation reads trajectory, contact, clearance and settling evidence together")


def _lane_line(m: LaneMetrics) -> str:
    stop = f"stops after {m.stop.distance:.4f} m at t={m.stop.time:.2f} s" if m.stop.stopped else m.stop.detail
    if m.max_tilt_deg is None:
        tilt = "; tilt not recorded"
    else:
        tilt = f"; max tilt {m.max_tilt_deg:.1f} deg" + (" (TUMBLED onto another face: not a sliding stop)"
                                                           if m.tumbled else "")
    agree = "" if m.pair_friction_agrees else f" DISAGREES with the pair rule's {m.pair_friction_rule:g}"
    pair = "none (no contact reported)" if m.pair_friction is None else f"{m.pair_friction:g}"
    return (f"{m.case} / {m.lane}: table {m.table_friction:g}, cube {m.cube_friction:g} -> engine pair "
            f"{pair}{agree}; {stop}; max |omega| {m.max_abs_omega:.2f} rad/s{tilt}"
            + ("" if m.stayed_on_table else "; LEFT THE TABLE"))


def _friction_baseline(lanes, ok, tol: "_Tolerances") -> Condition:
    title = "in the baseline friction run, the low-effective-friction lane travels farther before sustained stopping"
    if BASELINE not in ok:
        return Condition(id="friction_baseline", title=title, passed=False, evidence=f"{BASELINE}: no result")
    base = list(ok[BASELINE].metrics.lanes.values())
    low, high = lanes_by_pair(ok[BASELINE].metrics)
    lines = [_lane_line(m) for m in base]
    speed = ok[BASELINE].spec.initial_speed
    passed = low is not high and all(m.stayed_on_table for m in base)
    passed &= all(abs(m.initial_vx - speed) <= tol["initial_speed_match"] for m in base)
    # The engine's contact friction must agree with the Python copy of its rule; a disagreement fails visibly.
    passed &= all(m.pair_friction_agrees for m in base)
    if low.stop.stopped and high.stop.stopped:
        margin = low.stop.distance - high.stop.distance
        passed &= margin > tol["stop_distance_resolution"]
        lines.append(f"{low.lane} travels {margin:+.4f} m farther than {high.lane} "
                     f"(must exceed {tol.show('stop_distance_resolution')})")
    else:
        passed = False
        lines.append("a lane did not stop within the measured window: no stop distance to compare")
    return Condition(id="friction_baseline", title=title, passed=passed, evidence="\n".join(lines))


def _table_change(lanes, ok, tol: "_Tolerances") -> Condition:
    title = "lowering table friction changes the low-friction lane in the predicted direction and leaves the high lane nearly unchanged"
    missing = [n for n in (BASELINE, TABLE_030) if n not in ok]
    if missing:
        return Condition(id="table_friction_change", title=title, passed=False, evidence=f"no result: {missing}")
    changed = [c.field for c in field_changes(ok[BASELINE].spec, ok[TABLE_030].spec)]
    passed = changed == ["table.friction"]
    lines = [f"fields changed between runs: {changed or 'none'}" + ("" if passed else " (only table.friction may change)")]
    for lane in ok[BASELINE].spec.lanes:
        before, after = ok[BASELINE].metrics.lane(lane.name), ok[TABLE_030].metrics.lane(lane.name)
        lines.append(_lane_line(after))
        passed &= after.pair_friction_agrees
        delta = stop_change(before, after)
        if delta is None or before.pair_friction is None or after.pair_friction is None:
            passed = False
            lines.append(f"{lane.name}: not stopped within the measured window, or never in contact, in one run; "
                         "no distance to compare")
            continue
        if after.pair_friction < before.pair_friction:
            good = delta > tol["stop_distance_resolution"]
            lines.append(f"{lane.name}: pair {before.pair_friction:g} -> {after.pair_friction:g}, stop distance "
                         f"{before.stop.distance:.4f} -> {after.stop.distance:.4f} m ({delta:+.4f} m; predicted farther, "
                         f"must exceed {tol.show('stop_distance_resolution')})")
        else:
            good = abs(delta) <= tol["high_lane_unchanged"]
            lines.append(f"{lane.name}: pair {before.pair_friction:g} -> {after.pair_friction:g} (unchanged), stop distance "
                         f"{before.stop.distance:.4f} -> {after.stop.distance:.4f} m ({delta:+.4f} m; must stay within "
                         f"{tol.show('high_lane_unchanged')})")
        passed &= good
    return Condition(id="table_friction_change", title=title, passed=passed, evidence="\n".join(lines))
