"""Scoring engine: grade a prediction sheet against what the engine measured, item by item, under a rubric version.

Relationship items compare the student's predicted direction with the relation measured on the backend that ran
the case; a difference inside the reviewed tolerance is "inconclusive" (not counted either way). An item that needs
a case that failed or was never run is "not_measured" (no credit, visible); an item that reads a config breaking
the one-factor rule is "one_factor_violation" with the offending fields. Every item's feedback states the
prediction, the measured values with their backend, the tolerance and the verdict.
"""

from __future__ import annotations

import json
import re
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from pydantic import BaseModel

from .cases import BASELINE_CASES
from .friction import effective_pair_friction
from .metrics import ContactMetrics, LaneMetrics, align, contact_metrics, lane_metrics
from .results import CaseResult
from .rubrics import Item, Rubric, load_rubric
from .sheet import ConfigFinding, PredictionSheet, one_factor_findings, resolve_spec

Verdict = Literal["credit", "no_credit", "inconclusive", "one_factor_violation", "not_measured"]
SHEET_CASE_PREFIX = "sheet."
_RULES = {"max": max, "min": min, "mean": lambda a, b: (a + b) / 2, "product": lambda a, b: a * b}


class ItemGrade(BaseModel):
    id: str
    question: str
    part: str
    kind: str
    points: float
    score: float
    max_score: float  # 0 when inconclusive: neither credited nor penalized
    verdict: Verdict
    prediction: str
    expected: str
    feedback: str
    evidence: dict[str, float | int | None]
    backends: dict[str, str]
    tolerances: dict[str, str]


class GradeReport(BaseModel):
    lesson: str
    student: str
    rubric_version: str
    rubric_hash: str
    engine_version: str
    total: float
    max_total: float
    complete: bool  # False when any item could not be measured
    items: list[ItemGrade]
    config_findings: list[str]

    def item(self, item_id: str) -> ItemGrade:
        return next(i for i in self.items if i.id == item_id)


class NotMeasured(Exception):
    """A case this item needs has no valid measurement (failed, invalid, timed out or not run)."""


@dataclass
class Outcome:
    verdict: Verdict
    expected: str
    measured: str = ""
    evidence: dict[str, float | int | None] = field(default_factory=dict)
    backends: dict[str, str] = field(default_factory=dict)


def case_name(sheet: PredictionSheet, role_or_case: str) -> str:
    """Name a role's case runs under: the student's config is renamed so it never collides with a lesson case."""
    if role_or_case in sheet.configs.submitted():
        return SHEET_CASE_PREFIX + role_or_case
    return role_or_case


def cases_to_run(sheet: PredictionSheet, rubric: Rubric | None = None) -> list:
    """Every case grading needs: lesson cases not replaced by the sheet, plus its configs that obey the one-factor
    rule (a config that breaks it is graded as such, never run as if valid). Unique names."""
    rubric = rubric or load_rubric(sheet.lesson)
    findings = one_factor_findings(sheet, rubric)
    needed = ["N1", "N2", "N3", "N4", "friction-baseline"]
    specs = {}
    for name in needed:
        if name not in sheet.configs.submitted():
            specs[name] = BASELINE_CASES[name]
    for role, spec in sheet.configs.submitted().items():
        if findings[role].ok:
            run_name = case_name(sheet, role)
            specs[run_name] = type(spec).model_validate(
                {**spec.model_dump(exclude_computed_fields=True), "name": run_name}
            )
    return list(specs.values())


class Context:
    """What a check may read: the sheet, the rubric's tolerances, and measured metrics by role (cached)."""

    def __init__(self, sheet: PredictionSheet, results: Mapping[str, CaseResult], rubric: Rubric):
        self.sheet, self.results, self.rubric = sheet, results, rubric
        self._cache: dict = {}

    def tol(self, name: str) -> float:
        return self.rubric.tolerances[name].value

    def spec(self, role: str):
        return resolve_spec(self.sheet, role)

    def result(self, role: str) -> CaseResult:
        name = case_name(self.sheet, role)
        result = self.results.get(name)
        if result is None:
            raise NotMeasured(f"case {name} ({role}) was not run")
        if not result.ok:
            raise NotMeasured(f"case {name} ({role}) {result.status} on {result.backend}: {result.error}")
        return result

    def backend(self, role: str) -> str:
        return self.result(role).backend

    def contact(self, role: str) -> ContactMetrics:
        key = ("contact", role)
        if key not in self._cache:
            result = self.result(role)
            self._cache[key] = contact_metrics(result.spec, result.arrays)
        return self._cache[key]

    def lane(self, role: str, lane: str) -> LaneMetrics:
        key = ("lane", role, lane)
        if key not in self._cache:
            result = self.result(role)
            self._cache[key] = lane_metrics(result.spec, result.arrays, lane)
        return self._cache[key]

    def maybe(self, fn: Callable, *args):
        """Supporting evidence for a conceptual item: None when that case was not measured."""
        try:
            return fn(*args)
        except NotMeasured:
            return None


CHECKS: dict[str, Callable[[Context, Item, object], Outcome]] = {}


def check(name: str):
    def register(fn):
        CHECKS[name] = fn
        return fn
    return register


def _credit(ok: bool) -> Verdict:
    return "credit" if ok else "no_credit"


def _direction(delta: float, tol: float, *, down: str, up: str) -> str | None:
    """Measured direction of a difference; None when it lies inside the resolution tolerance."""
    if abs(delta) <= tol:
        return None
    return up if delta > 0 else down


def _relation_verdict(predicted: str, measured: list[str | None]) -> Verdict:
    """A decisive measurement against the prediction refutes it; otherwise any unresolved one leaves it open."""
    if any(m is not None and m != predicted for m in measured):
        return "no_credit"
    if any(m is None for m in measured):
        return "inconclusive"
    return "credit"


def _close(value: float, target: float, rel: float) -> bool:
    return abs(value - target) <= rel * abs(target)


# --- Part A ---------------------------------------------------------------------------------------------------


@check("sample_counts")
def _sample_counts(ctx: Context, item: Item, a) -> Outcome:
    counts = {n: ctx.spec(n).sample_count for n in ("N1", "N2", "N3", "N4")}
    want150 = sorted(n for n, c in counts.items() if c == 150)
    want75 = sorted(n for n, c in counts.items() if c == 75)
    ok = sorted(a.samples_150) == want150 and sorted(a.samples_75) == want75
    return Outcome(_credit(ok), f"150 samples: {want150}, 75 samples: {want75}",
                   "computed from the configs: " + ", ".join(f"{n} {c}" for n, c in counts.items()),
                   evidence={f"{n}_samples": c for n, c in counts.items()})


@check("proxy_direction")
def _proxy_direction(ctx: Context, item: Item, a) -> Outcome:
    tol = ctx.tol("proxy_resolution")
    measured, parts, evidence, backends = [], [], {}, {}
    for fewer, more in (("N1", "N2"), ("N3", "N4")):
        p0, p1 = ctx.contact(fewer).penetration_proxy, ctx.contact(more).penetration_proxy
        m = _direction(p1 - p0, tol, down="decrease", up="increase")
        measured.append(m)
        evidence |= {f"{fewer}_proxy_m": p0, f"{more}_proxy_m": p1}
        backends |= {fewer: ctx.backend(fewer), more: ctx.backend(more)}
        parts.append(f"{fewer} {p0:.6f} m -> {more} {p1:.6f} m ({m or 'inside tolerance'})")
    return Outcome(_relation_verdict(a.direction, measured), "the direction measured at fixed dt",
                   "; ".join(parts), evidence, backends)


@check("n1_n4_agree")
def _n1_n4_agree(ctx: Context, item: Item, a) -> Outcome:
    r1, r4 = ctx.result("N1"), ctx.result("N4")
    al = align("N1", r1.arrays, "N4", r4.arrays)
    if al.shared_samples == 0:
        raise NotMeasured("N1 and N4 share no sample times")
    dz = al.max_abs_diff["z"]
    agree = dz <= ctx.tol("n1_n4_max_dz")
    return Outcome(_credit(a.agree == agree), f"agree={agree}",
                   f"max |dz| = {dz:.3g} m over {al.shared_samples} shared times {al.first_shared_times}...",
                   {"max_abs_dz_m": dz, "max_abs_dvz_m_s": al.max_abs_diff["vz"], "shared_samples": al.shared_samples},
                   {"N1": r1.backend, "N4": r4.backend})


@check("array_lengths")
def _array_lengths(ctx: Context, item: Item, a) -> Outcome:
    r1, r4 = ctx.result("N1"), ctx.result("N4")
    n1, n4 = len(r1.arrays["t"]), len(r4.arrays["t"])
    s1, s4 = r1.spec.substep_dt, r4.spec.substep_dt
    same = n1 == n4
    return Outcome(_credit(a.same_length == same), f"same_length={same}",
                   f"substep_dt N1 {s1:g} s, N4 {s4:g} s; measured array lengths N1 {n1}, N4 {n4}",
                   {"N1_samples": n1, "N4_samples": n4, "N1_substep_dt_s": s1, "N4_substep_dt_s": s4},
                   {"N1": r1.backend, "N4": r4.backend})


@check("one_number")
def _one_number(ctx: Context, item: Item, a) -> Outcome:
    m1, m2 = ctx.maybe(ctx.contact, "N1"), ctx.maybe(ctx.contact, "N2")
    measured, evidence, backends = "no measured example available", {}, {}
    if m1 and m2:
        evidence = {"N1_proxy_m": m1.penetration_proxy, "N2_proxy_m": m2.penetration_proxy,
                    "N1_separation_samples": m1.separation_samples, "N2_separation_samples": m2.separation_samples}
        backends = {"N1": ctx.backend("N1"), "N2": ctx.backend("N2")}
        measured = (f"N1 proxy {m1.penetration_proxy:.6f} m with {m1.separation_samples} separation samples; "
                    f"N2 proxy {m2.penetration_proxy:.6f} m with {m2.separation_samples} separation samples")
    return Outcome(_credit(a.one_number_decides is False), "no: read proxy, contact, clearance and trajectory together",
                   measured, evidence, backends)


# --- Part B ---------------------------------------------------------------------------------------------------


def _pairs(spec) -> dict[str, float]:
    return {lane.name: effective_pair_friction(spec.table.friction, lane.friction) for lane in spec.lanes}


@check("pair_value_changes")
def _pair_value_changes(ctx: Context, item: Item, a) -> Outcome:
    before, after = _pairs(ctx.spec("friction-baseline")), _pairs(ctx.spec("table_exercise"))
    changed = sorted(lane for lane in before if abs(after.get(lane, np.nan) - before[lane]) > 1e-12 or lane not in after)
    return Outcome(_credit(sorted(a.lanes) == changed), f"lanes {changed}",
                   "computed with the 1.3.3 pair rule: " + ", ".join(
                       f"{lane} {before[lane]:g} -> {after.get(lane)}" for lane in before),
                   {f"{lane}_pair_baseline": before[lane] for lane in before}
                   | {f"{lane}_pair_modified": after.get(lane) for lane in before})


def _stop_distances(ctx: Context, role: str) -> dict[str, float | None]:
    return {lane.name: ctx.lane(role, lane.name).stop.distance for lane in ctx.spec(role).lanes}


@check("lane_travels_farther")
def _lane_travels_farther(ctx: Context, item: Item, a) -> Outcome:
    low, high = ctx.lane("friction-baseline", "low"), ctx.lane("friction-baseline", "high")
    evidence = {"low_stop_distance_m": low.stop.distance, "high_stop_distance_m": high.stop.distance,
                "low_stop_time_s": low.stop.time, "high_stop_time_s": high.stop.time,
                "low_pair": low.pair_friction, "high_pair": high.pair_friction}
    backends = {"friction-baseline": ctx.backend("friction-baseline")}
    if not (low.stop.stopped and high.stop.stopped):
        return Outcome("inconclusive", "the lane with the longer sustained-stop distance",
                       f"low: {low.stop.detail}; high: {high.stop.detail}", evidence, backends)
    farther = _direction(low.stop.distance - high.stop.distance, ctx.tol("stop_distance_resolution"),
                         down="high", up="low")
    measured = (f"stop distance low {low.stop.distance:.4f} m (pair {low.pair_friction:g}, stopped at "
                f"{low.stop.time:.2f} s), high {high.stop.distance:.4f} m (pair {high.pair_friction:g}, stopped at "
                f"{high.stop.time:.2f} s); stop time and distance need not rank alike")
    return Outcome(_relation_verdict(a.lane, [farther]), f"the lane measured farther ({farther or 'unresolved'})",
                   measured, evidence, backends)


def _lane_changes(ctx: Context) -> tuple[dict[str, float | None], dict, dict]:
    before, after = _stop_distances(ctx, "friction-baseline"), _stop_distances(ctx, "table_exercise")
    deltas = {lane: (after[lane] - before[lane]) if before[lane] is not None and after.get(lane) is not None
              else None for lane in before}
    evidence = {f"{lane}_baseline_m": before[lane] for lane in before} | {
        f"{lane}_modified_m": after.get(lane) for lane in before} | {f"{lane}_delta_m": d for lane, d in deltas.items()}
    backends = {"friction-baseline": ctx.backend("friction-baseline"),
                case_name(ctx.sheet, "table_exercise"): ctx.backend("table_exercise")}
    return deltas, evidence, backends


def _describe_changes(deltas: dict, evidence: dict) -> str:
    return "; ".join(
        f"{lane}: {evidence[f'{lane}_baseline_m']} -> {evidence[f'{lane}_modified_m']} m"
        if d is None else
        f"{lane}: {evidence[f'{lane}_baseline_m']:.4f} -> {evidence[f'{lane}_modified_m']:.4f} m (delta {d:+.4f} m)"
        for lane, d in deltas.items())


@check("lane_unchanged")
def _lane_unchanged(ctx: Context, item: Item, a) -> Outcome:
    deltas, evidence, backends = _lane_changes(ctx)
    if any(d is None for d in deltas.values()):
        return Outcome("inconclusive", "lanes whose stop distance changes within tolerance",
                       "a lane did not stop within the window: " + _describe_changes(deltas, evidence), evidence, backends)
    tol = ctx.tol("high_lane_unchanged")
    unchanged = sorted(lane for lane, d in deltas.items() if abs(d) <= tol)
    word = {0: "neither", 2: "both"}.get(len(unchanged)) or unchanged[0]
    return Outcome(_credit(a.lane == word), word, _describe_changes(deltas, evidence), evidence, backends)


@check("color_layer")
def _color_layer(ctx: Context, item: Item, a) -> Outcome:
    ok = a.color_layer == "visual" and a.affects_results is False
    return Outcome(_credit(ok), "visual layer; affects neither result",
                   "color is not an input of the pair rule max(table, cube) nor of any metric")


# --- concept checkpoints --------------------------------------------------------------------------------------


def _timing_outcome(ctx: Context, spec, a) -> Outcome:
    rel = ctx.tol("computed_relative")
    ok = (_close(a.substep_dt.si, spec.substep_dt, rel) and a.samples == spec.sample_count
          and a.internal_updates == spec.internal_updates)
    return Outcome(_credit(ok),
                   f"substep_dt {spec.substep_dt:g} s, {spec.sample_count} samples, {spec.internal_updates} internal updates",
                   f"computed from {spec.name}: dt {spec.dt:g} s, substeps {spec.substeps}, duration {spec.duration:g} s",
                   {"substep_dt_s": spec.substep_dt, "samples": spec.sample_count,
                    "internal_updates": spec.internal_updates})


@check("timing_n4")
def _timing_n4(ctx: Context, item: Item, a) -> Outcome:
    return _timing_outcome(ctx, BASELINE_CASES["N4"], a)


@check("equal_steps_invalid")
def _equal_steps(ctx: Context, item: Item, a) -> Outcome:
    n1, n3 = BASELINE_CASES["N1"], BASELINE_CASES["N3"]
    covered = n1.n_steps * n3.dt
    return Outcome(_credit(a.reason == "unequal_simulated_duration"), "unequal_simulated_duration",
                   f"{n1.n_steps} steps cover {n1.n_steps * n1.dt:g} s at dt {n1.dt:g} but {covered:g} s at dt {n3.dt:g}",
                   {"steps": n1.n_steps, "duration_at_dt_0.01_s": n1.n_steps * n1.dt, "duration_at_dt_0.02_s": covered})


@check("shared_times")
def _shared_times(ctx: Context, item: Item, a) -> Outcome:
    measured, evidence, backends = "", {}, {}
    r1, r4 = ctx.maybe(ctx.result, "N1"), ctx.maybe(ctx.result, "N4")
    if r1 and r4:
        al = align("N1", r1.arrays, "N4", r4.arrays)
        measured = f"N1 {al.samples_a} samples, N4 {al.samples_b}; only {al.shared_samples} times are shared"
        evidence = {"N1_samples": al.samples_a, "N4_samples": al.samples_b, "shared_samples": al.shared_samples}
        backends = {"N1": r1.backend, "N4": r4.backend}
    return Outcome(_credit(a.reason == "unshared_samples_have_no_counterpart"), "unshared_samples_have_no_counterpart",
                   measured, evidence, backends)


@check("zero_contact")
def _zero_contact(ctx: Context, item: Item, a) -> Outcome:
    evidence, backends = {}, {}
    for role in ("N1", "N2", "N3", "N4"):
        r = ctx.maybe(ctx.result, role)
        if r is None:
            continue
        m = ctx.contact(role)
        if m.first_contact_index is None:
            continue
        after = slice(m.first_contact_index, None)
        zero = r.arrays["contact_count"][after] == 0
        # Zero contacts with the bottom still within the separation tolerance: no geometric evidence of rebound.
        unsupported = zero & (r.arrays["clearance"][after] <= r.spec.separation_tolerance)
        evidence[f"{role}_zero_contact_samples"] = int(zero.sum())
        evidence[f"{role}_zero_contact_without_separation"] = int(unsupported.sum())
        backends[role] = r.backend
    measured = ", ".join(f"{k} {v}" for k, v in evidence.items()) or "no measured contact case available"
    return Outcome(_credit(a.proves_rebound is False), "no: also require clearance above tolerance",
                   measured, evidence, backends)


@check("pair_value_low")
def _pair_value_low(ctx: Context, item: Item, a) -> Outcome:
    want = effective_pair_friction(0.50, 0.10)
    return Outcome(_credit(abs(a.pair_friction - want) <= ctx.tol("pair_friction_abs")), f"{want:g}",
                   "Genesis 1.3.3 rule max(table, cube) after friction ratios", {"pair_friction": want})


@check("pair_rule")
def _pair_rule(ctx: Context, item: Item, a) -> Outcome:
    tol, rule = ctx.tol("pair_friction_abs"), _RULES[a.pair_rule]
    rows = [(spec.table.friction, lane.friction) for spec in (ctx.spec("friction-baseline"), ctx.spec("table_exercise"))
            for lane in spec.lanes]
    ok = all(abs(rule(t, c) - effective_pair_friction(t, c)) <= tol for t, c in rows)
    return Outcome(_credit(ok), "max",
                   "engine pair values: " + ", ".join(f"({t:g}, {c:g}) -> {effective_pair_friction(t, c):g}"
                                                      for t, c in rows))


def _color_name(rgb) -> str:
    return "blue" if rgb[2] >= max(rgb[0], rgb[1]) else "orange" if rgb[0] > rgb[2] else "other"


@check("color_swap")
def _color_swap(ctx: Context, item: Item, a) -> Outcome:
    spec = ctx.spec("friction-baseline")
    parts, evidence, backends = [], {}, {}
    if ctx.maybe(ctx.result, "friction-baseline"):
        for lane in spec.lanes:
            m = ctx.lane("friction-baseline", lane.name)
            parts.append(f"{_color_name(lane.color)} lane '{lane.name}' (pair {m.pair_friction:g}) stopped after "
                         f"{m.stop.distance if m.stop.distance is None else round(m.stop.distance, 4)} m")
            evidence[f"{lane.name}_stop_distance_m"] = m.stop.distance
            evidence[f"{lane.name}_pair"] = m.pair_friction
        backends["friction-baseline"] = ctx.backend("friction-baseline")
    measured = "; ".join(parts) + "; the distances follow pair friction, color is not an engine input"
    return Outcome(_credit(a.color_effect == "none"), "none", measured, evidence, backends)


@check("one_sample_stop")
def _one_sample_stop(ctx: Context, item: Item, a) -> Outcome:
    parts, evidence, backends = [], {}, {}
    r = ctx.maybe(ctx.result, "friction-baseline")
    if r:
        for lane in r.spec.lanes:
            vx, t = r.arrays[f"{lane.name}_vx"], r.arrays["t"]
            below = np.flatnonzero(np.abs(vx) < r.spec.stop_speed)
            stop = ctx.lane("friction-baseline", lane.name).stop
            first = float(t[below[0]]) if below.size else None
            early = int(np.sum(below < stop.index)) if stop.stopped else int(below.size)
            evidence |= {f"{lane.name}_first_below_threshold_s": first, f"{lane.name}_sustained_stop_s": stop.time,
                         f"{lane.name}_isolated_samples_before_stop": early}
            parts.append(f"{lane.name}: first |vx| < {r.spec.stop_speed} at {first} s, sustained stop at {stop.time} s")
        backends["friction-baseline"] = r.backend
    return Outcome(_credit(a.establishes_stop is False), "no: the hold interval must stay below threshold",
                   "; ".join(parts), evidence, backends)


# --- hands-on exercise and extension --------------------------------------------------------------------------


@check("exercise_pair_values")
def _exercise_pairs(ctx: Context, item: Item, a) -> Outcome:
    tol = ctx.tol("pair_friction_abs")
    want = {"baseline": _pairs(ctx.spec("friction-baseline")), "modified": _pairs(ctx.spec("table_exercise"))}
    ok = all(abs(getattr(getattr(a, run), lane) - want[run][lane]) <= tol for run in want for lane in ("low", "high"))
    return Outcome(_credit(ok), json.dumps(want), "computed from the configs with the 1.3.3 pair rule",
                   {f"{run}_{lane}": v for run, pairs in want.items() for lane, v in pairs.items()})


@check("low_lane_direction")
def _low_lane_direction(ctx: Context, item: Item, a) -> Outcome:
    deltas, evidence, backends = _lane_changes(ctx)
    d = deltas["low"]
    measured = None if d is None else _direction(d, ctx.tol("stop_distance_resolution"), down="shorter", up="farther")
    return Outcome(_relation_verdict(a.low, [measured]), f"measured {measured or 'unresolved'}",
                   _describe_changes(deltas, evidence), evidence, backends)


@check("high_lane_direction")
def _high_lane_direction(ctx: Context, item: Item, a) -> Outcome:
    deltas, evidence, backends = _lane_changes(ctx)
    d = deltas["high"]
    if d is None:
        return Outcome("inconclusive", "unchanged within tolerance", _describe_changes(deltas, evidence),
                       evidence, backends)
    # The control lane: "unchanged" is itself the relation under test, decided by the reviewed margin.
    measured = _direction(d, ctx.tol("high_lane_unchanged"), down="shorter", up="farther") or "unchanged"
    return Outcome(_credit(a.high == measured), measured, _describe_changes(deltas, evidence), evidence, backends)


@check("reported_stops")
def _reported_stops(ctx: Context, item: Item, a) -> Outcome:
    tol = ctx.tol("reported_stop_distance")
    ok, parts, evidence = True, [], {}
    for run, role in (("baseline", "friction-baseline"), ("modified", "table_exercise")):
        for lane in ("low", "high"):
            stop = ctx.lane(role, lane).stop
            reported = getattr(getattr(a, run), lane)
            if reported == "not_stopped":
                match = not stop.stopped
            else:
                match = stop.stopped and abs(reported.si - stop.distance) <= tol
            ok &= bool(match)
            evidence[f"{run}_{lane}_stop_distance_m"] = stop.distance
            parts.append(f"{run} {lane}: {round(stop.distance, 4) if stop.stopped else 'not stopped'}"
                         f"{'' if match else ' (mismatch)'}")
    backends = {"friction-baseline": ctx.backend("friction-baseline"),
                case_name(ctx.sheet, "table_exercise"): ctx.backend("table_exercise")}
    return Outcome(_credit(ok), "the measured sustained stops", "; ".join(parts), evidence, backends)


@check("exercise_one_factor")
def _exercise_one_factor(ctx: Context, item: Item, a) -> Outcome:
    # Reached only when the config obeys the rule (violations are decided before any check runs).
    changes = one_factor_findings(ctx.sheet, ctx.rubric)["table_exercise"]
    return Outcome(_credit(a.only_table_friction_changed is True), "true", changes.describe())


@check("engine_version")
def _engine_version(ctx: Context, item: Item, a) -> Outcome:
    want = ctx.rubric.engine_version
    ran = ctx.maybe(ctx.result, "friction-baseline")
    measured = f"cases ran on genesis {ran.provenance.versions.get('genesis')}" if ran and ran.provenance else ""
    ok = re.search(rf"(?<![0-9.]){re.escape(want)}(?![0-9.])", a.engine_version) is not None
    return Outcome(_credit(ok), want, measured)


@check("timing_extension")
def _timing_extension(ctx: Context, item: Item, a) -> Outcome:
    out = _timing_outcome(ctx, ctx.spec("extension"), a)
    n1 = ctx.spec("N1")
    out.evidence["work_vs_N1"] = ctx.spec("extension").internal_updates / n1.internal_updates
    out.measured += f"; {out.evidence['work_vs_N1']:g}x the internal updates of N1"
    return out


@check("may_improve")
def _may_improve(ctx: Context, item: Item, a) -> Outcome:
    if "penetration_proxy" not in a.may_improve:
        return Outcome("no_credit", "penetration_proxy among what may improve", "not listed")
    p1, p5 = ctx.contact("N1").penetration_proxy, ctx.contact("extension").penetration_proxy
    measured = _direction(p5 - p1, ctx.tol("proxy_resolution"), down="decrease", up="increase")
    ext = case_name(ctx.sheet, "extension")
    return Outcome(_relation_verdict("decrease", [measured]), "penetration proxy may decrease",
                   f"proxy N1 {p1:.6f} m -> {ext} {p5:.6f} m ({measured or 'inside tolerance'})",
                   {"N1_proxy_m": p1, "extension_proxy_m": p5},
                   {"N1": ctx.backend("N1"), ext: ctx.backend("extension")})


@check("not_guaranteed")
def _not_guaranteed(ctx: Context, item: Item, a) -> Outcome:
    tol = ctx.tol("proxy_resolution")
    worse, evidence, backends = [], {}, {}
    for fewer, more in (("N1", "N2"), ("N3", "N4"), ("N1", "extension")):
        m0, m1 = ctx.maybe(ctx.contact, fewer), ctx.maybe(ctx.contact, more)
        if m0 is None or m1 is None:
            continue
        backends |= {case_name(ctx.sheet, r): ctx.backend(r) for r in (fewer, more)}
        if m1.separation_samples > m0.separation_samples:
            worse.append(f"{more} has {m1.separation_samples} geometric-separation samples vs {m0.separation_samples} in {fewer}")
            evidence[f"{fewer}_separation_samples"] = m0.separation_samples
            evidence[f"{more}_separation_samples"] = m1.separation_samples
        if m1.penetration_proxy - m0.penetration_proxy > tol:
            worse.append(f"{more} proxy {m1.penetration_proxy:.6f} m > {fewer} {m0.penetration_proxy:.6f} m")
    measured = ("measured counterexamples with more substeps: " + "; ".join(worse)) if worse else \
        "no counterexample among the measured cases (one scene is still no guarantee)"
    return Outcome(_credit(a.every_diagnostic_improves is False), "false: improvement is not guaranteed",
                   measured, evidence, backends)


# --- the engine -----------------------------------------------------------------------------------------------


def _prediction(answer) -> str:
    return json.dumps(answer.model_dump(mode="json", exclude={"explanation"}), separators=(", ", ": "))


def _tolerances(rubric: Rubric, item: Item) -> dict[str, str]:
    return {name: f"{rubric.tolerances[name].value:g} {rubric.tolerances[name].unit}" for name in item.tolerances}


_VERDICT_TEXT = {
    "credit": "credit: the prediction matches",
    "no_credit": "no credit: the prediction does not match",
    "inconclusive": "inconclusive: the measured difference is inside the reviewed tolerance, so the direction is "
                    "neither credited nor penalized (not counted)",
    "one_factor_violation": "one-factor violation: too many inputs changed at once, the comparison is not interpretable",
    "not_measured": "not measured: no valid result for a case this item needs; no credit until it is measured",
}


def _grade_item(ctx: Context, item: Item, findings: dict[str, ConfigFinding]) -> ItemGrade:
    answer = getattr(ctx.sheet.answers, item.id)
    broken = [findings[r] for r in item.roles if r in findings and not findings[r].ok]
    if broken:
        outcome = Outcome("one_factor_violation", "a one-factor config", "; ".join(f.describe() for f in broken))
    else:
        try:
            outcome = CHECKS[item.check](ctx, item, answer)
        except NotMeasured as exc:
            outcome = Outcome("not_measured", "a measured result", str(exc))
    tolerances = _tolerances(ctx.rubric, item)
    feedback = [f"Prediction: {_prediction(answer)}.", f"Expected: {outcome.expected}."]
    if outcome.measured:
        on = ", ".join(f"{case} on {backend}" for case, backend in outcome.backends.items())
        feedback.append(f"Evidence: {outcome.measured}" + (f" [{on}]." if on else "."))
    if tolerances:
        feedback.append("Tolerance: " + ", ".join(f"{k} = {v}" for k, v in tolerances.items()) + ".")
    feedback.append(f"Verdict: {_VERDICT_TEXT[outcome.verdict]}.")
    counted = outcome.verdict != "inconclusive"
    return ItemGrade(
        id=item.id, question=item.question, part=item.part, kind=item.kind, points=item.points,
        score=item.points if outcome.verdict == "credit" else 0.0,
        max_score=item.points if counted else 0.0,
        verdict=outcome.verdict, prediction=_prediction(answer), expected=outcome.expected,
        feedback=" ".join(feedback), evidence=outcome.evidence, backends=outcome.backends, tolerances=tolerances,
    )


def grade_sheet(sheet: PredictionSheet, results: Mapping[str, CaseResult], rubric: Rubric | None = None) -> GradeReport:
    """Grade every rubric item; failed or missing results give visible not_measured items, never a crash or credit."""
    rubric = rubric or load_rubric(sheet.lesson)
    if rubric.lesson != sheet.lesson:
        raise ValueError(f"rubric is for lesson {rubric.lesson}, the sheet for {sheet.lesson}")
    ctx = Context(sheet, results, rubric)
    findings = one_factor_findings(sheet, rubric)
    items = [_grade_item(ctx, item, findings) for item in rubric.items]
    return GradeReport(
        lesson=sheet.lesson, student=sheet.student, rubric_version=rubric.version, rubric_hash=rubric.content_hash,
        engine_version=rubric.engine_version,
        total=sum(i.score for i in items), max_total=sum(i.max_score for i in items),
        complete=all(i.verdict != "not_measured" for i in items),
        items=items, config_findings=[f.describe() for f in findings.values()],
    )
