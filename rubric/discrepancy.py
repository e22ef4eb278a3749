"""Backend-discrepancy comparison: one case spec measured twice (backend, precision or execution mode), classified.

Both measurements are kept and compared at their shared sample times, array by array and metric by metric, under
the reviewed audit tolerances (rubric/lessons/L03-audit-v1.yaml), and the lesson's qualitative relations are judged
on each side with the same rules and grading tolerances the lab check and the scoring use (rubric.relations,
rubric L03's published version). Classification, most severe first: relation_changed (a qualitative relation
differs), numeric_drift (a difference beyond its reviewed tolerance), within_tolerance, identical (every shared
array bit-equal and every metric equal).
"""

from __future__ import annotations

import json
import re
from collections.abc import Mapping
from typing import Literal

import numpy as np
import yaml
from pydantic import BaseModel, ConfigDict, model_validator
from pydantic_core import PydanticCustomError

from .metrics import ContactMetrics, FrictionMetrics, LaneMetrics, _ticks, align
from .relations import cases_agree, direction, lanes_by_pair, proxy_change, stop_change
from .results import FRAME_FIELDS, CaseResult
from . import rubrics
from .rubrics import VERSION_PATTERN, ReviewRecord, Rubric, Tolerance, load_rubric, version_key
from .specs import ContactCase, field_changes

Classification = Literal["identical", "within_tolerance", "numeric_drift", "relation_changed"]
Value = bool | int | float | None


# --- the reviewed audit tolerances -----------------------------------------------------------------------------

class AuditTolerances(BaseModel):
    """The reviewed ranges one lesson's audit classifies differences with, and which quantity each one covers."""

    model_config = ConfigDict(extra="forbid", frozen=True, strict=True)

    lesson: str
    version: str
    engine_version: str
    grading_rubric: str  # the rubric version whose grading resolutions the values were derived from
    review: ReviewRecord
    tolerances: dict[str, Tolerance]
    quantities: dict[str, str]  # "contact.z" / "lane.vx" -> tolerance name

    @model_validator(mode="after")
    def _consistent(self) -> "AuditTolerances":
        unknown = sorted({t for t in self.quantities.values() if t not in self.tolerances})
        if unknown:
            raise PydanticCustomError("unknown_tolerance", "quantities: unknown tolerances {t}", {"t": unknown})
        unused = sorted(set(self.tolerances) - set(self.quantities.values()))
        if unused:
            raise PydanticCustomError("unused_tolerance", "tolerances: {t} cover no quantity", {"t": unused})
        return self

    @property
    def label(self) -> str:
        return f"{self.lesson}-audit-v{self.version}"

    def of(self, quantity: str) -> tuple[str, Tolerance]:
        """(name, record) of the tolerance a quantity is held to; KeyError names a quantity nobody reviewed."""
        try:
            name = self.quantities[quantity]
        except KeyError:
            raise KeyError(f"{self.label} reviews no tolerance for {quantity!r}") from None
        return name, self.tolerances[name]


def audit_versions(lesson: str = "L03") -> list[str]:
    """Audit tolerance versions shipped for a lesson, oldest first (files named LESSON-audit-vVERSION.yaml)."""
    pattern = re.compile(rf"^{re.escape(lesson)}-audit-v([0-9.]+)\.yaml$")
    folder = rubrics.lesson_folder(lesson)
    found = [m.group(1) for p in folder.glob("*.yaml") if (m := pattern.match(p.name))] if folder else []
    return sorted((v for v in found if re.match(VERSION_PATTERN, v)), key=version_key)


def load_audit_tolerances(lesson: str = "L03", version: str | None = None) -> AuditTolerances:
    """A lesson's audit tolerances at `version`, or the latest; the file's own lesson/version must agree."""
    versions = audit_versions(lesson)
    if not versions:
        raise LookupError(f"no audit tolerance files for lesson {lesson!r} in "
                          f"{rubrics.lesson_folder(lesson) or 'no installed lesson'}")
    version = version or versions[-1]
    if version not in versions:
        raise LookupError(f"lesson {lesson} has no audit tolerances version {version!r}; known: {', '.join(versions)}")
    data = yaml.safe_load((rubrics.lesson_folder(lesson) / f"{lesson}-audit-v{version}.yaml").read_text())
    loaded = AuditTolerances.model_validate_json(json.dumps(data, default=str))
    if (loaded.lesson, loaded.version) != (lesson, version):
        raise ValueError(f"{lesson}-audit-v{version}.yaml declares lesson {loaded.lesson} version {loaded.version}")
    return loaded


# --- what a comparison reports -------------------------------------------------------------------------------

class ArrayDiff(BaseModel):
    """One array at the shared sample times: largest and RMS difference (over every component of 2-D arrays)."""

    name: str
    unit: str
    shared_samples: int
    max_abs: float | None  # None: the two records share no sample time
    rms: float | None
    bit_equal: bool
    tolerance: str
    tolerance_value: float
    within: bool


class MetricDiff(BaseModel):
    """One stored metric on both sides; booleans and absent values (None: not stopped, no contact) must be equal."""

    name: str
    unit: str
    left: Value
    right: Value
    abs_diff: float | None
    tolerance: str | None
    within: bool


class RelationCheck(BaseModel):
    """A qualitative relation of the lesson judged on each side; None where a side cannot decide it."""

    id: str
    description: str
    left: bool | None
    right: bool | None
    changed: bool
    evidence: str


class CaseComparison(BaseModel):
    case: str
    axes: dict[str, list[str]]  # the axes that differ, e.g. {"precision": ["32", "64"]}; empty for a repeat
    left: str  # "cpu / 32-bit / warm"
    right: str
    shared_times: int
    arrays: list[ArrayDiff]
    metrics: list[MetricDiff]
    relations: list[RelationCheck]
    classification: Classification
    tolerances_version: str
    summary: str


# --- refusing what must not be compared ----------------------------------------------------------------------

def _check_comparable(left: CaseResult, right: CaseResult) -> None:
    """ValueError naming the field when the two results are not one spec apart from backend and precision."""
    for side, r in (("left", left), ("right", right)):
        if not (r.ok and r.arrays):
            raise ValueError(f"{side}.status: {r.spec.name} is {r.status} ({r.error}); only measured results compare")
    changes = [c for c in field_changes(left.spec, right.spec) if c.field not in ("backend", "precision")]
    if changes:
        fields = "; ".join(f"{c.field}: {c.baseline!r} vs {c.config!r}" for c in changes)
        raise ValueError(f"{left.spec.name} and {right.spec.name} are different specs ({fields}); "
                         "only backend and precision may differ")


def side_label(r: CaseResult) -> str:
    mode = r.provenance.execution_mode if r.provenance else "?"
    precision = r.provenance.precision if r.provenance else r.spec.precision
    return f"{r.backend} / {precision}-bit / {mode}"


def _axes(left: CaseResult, right: CaseResult) -> dict[str, list[str]]:
    values = {
        "backend": (left.backend, right.backend),
        "precision": tuple(r.provenance.precision if r.provenance else r.spec.precision for r in (left, right)),
        "mode": tuple(r.provenance.execution_mode if r.provenance else "?" for r in (left, right)),
    }
    return {axis: list(pair) for axis, pair in values.items() if pair[0] != pair[1]}


# --- arrays and metrics --------------------------------------------------------------------------------------

def _quantity(result: CaseResult, name: str) -> str:
    """'contact.z', or 'lane.vx' for a lane's 'low_vx': the key its audit tolerance is reviewed under."""
    if isinstance(result.spec, ContactCase):
        return f"contact.{name}"
    for lane in result.spec.lanes:
        if name.startswith(f"{lane.name}_"):
            return f"lane.{name[len(lane.name) + 1:]}"
    raise KeyError(f"array {name!r} belongs to no lane of {result.spec.name}")


def shared_indices(left: CaseResult, right: CaseResult) -> tuple[np.ndarray, np.ndarray]:
    """Indices of the sample times both records hold (exact to the nanosecond, as rubric.metrics.align matches them)."""
    _, il, ir = np.intersect1d(_ticks(left.arrays["t"]), _ticks(right.arrays["t"]), assume_unique=True,
                               return_indices=True)
    return il, ir


def array_diffs(left: CaseResult, right: CaseResult, tolerances: AuditTolerances) -> list[ArrayDiff]:
    il, ir = shared_indices(left, right)
    same_axis = len(il) == len(left.arrays["t"]) == len(right.arrays["t"])
    out = []
    for name in sorted(set(left.arrays) & set(right.arrays)):
        a, b = left.arrays[name], right.arrays[name]
        if name == "t" or name in FRAME_FIELDS or a.ndim == 0:  # the axis itself, pictures, per-run constants
            continue
        tol_name, tol = tolerances.of(_quantity(left, name))
        d = a[il].astype(np.float64) - b[ir].astype(np.float64)
        max_abs = float(np.max(np.abs(d))) if d.size else None
        rms = float(np.sqrt(np.mean(d * d))) if d.size else None
        out.append(ArrayDiff(name=name, unit=tol.unit, shared_samples=len(il), max_abs=max_abs, rms=rms,
                             bit_equal=same_axis and np.array_equal(a, b), tolerance=tol_name,
                             tolerance_value=tol.value, within=max_abs is not None and max_abs <= tol.value))
    return out


CONTACT_METRICS = ("penetration_proxy", "min_z", "min_clearance", "final_clearance", "tail_settling_error",
                   "tail_peak_to_peak", "first_contact_time", "contact_samples", "separation_samples",
                   "upward_samples_after_contact", "max_upward_velocity_after_contact", "max_tilt_deg", "passed_through")
LANE_METRICS = ("table_friction", "cube_friction", "pair_friction", "pair_friction_agrees", "initial_vx", "stopped",
                "stop_distance", "stop_time", "final_displacement", "max_abs_omega", "max_tilt_deg", "stayed_on_table")


def _lane_value(m: LaneMetrics, name: str) -> Value:
    if name in ("stopped", "stop_distance", "stop_time"):
        return getattr(m.stop, {"stopped": "stopped", "stop_distance": "distance", "stop_time": "time"}[name])
    return getattr(m, name)


def _metric(name: str, quantity: str, left: Value, right: Value, tolerances: AuditTolerances) -> MetricDiff:
    if isinstance(left, bool) or isinstance(right, bool):
        return MetricDiff(name=name, unit="yes/no", left=left, right=right, abs_diff=None, tolerance=None,
                          within=left == right)
    tol_name, tol = tolerances.of(quantity)
    if left is None or right is None:  # not stopped / no contact on a side: only equal absence agrees
        return MetricDiff(name=name, unit=tol.unit, left=left, right=right, abs_diff=None, tolerance=tol_name,
                          within=left is None and right is None)
    diff = abs(float(left) - float(right))
    return MetricDiff(name=name, unit=tol.unit, left=left, right=right, abs_diff=diff, tolerance=tol_name,
                      within=diff <= tol.value)


def metric_diffs(left: CaseResult, right: CaseResult, tolerances: AuditTolerances) -> list[MetricDiff]:
    ml, mr = left.metrics, right.metrics
    if isinstance(ml, ContactMetrics):
        return [_metric(n, f"contact.{n}", getattr(ml, n), getattr(mr, n), tolerances) for n in CONTACT_METRICS]
    return [_metric(f"{lane}.{n}", f"lane.{n}", _lane_value(ml.lane(lane), n), _lane_value(mr.lane(lane), n), tolerances)
            for lane in ml.lanes for n in LANE_METRICS]


# --- qualitative relations -----------------------------------------------------------------------------------

def _relation(id: str, description: str, left: tuple[bool | None, str], right: tuple[bool | None, str],
              labels: tuple[str, str]) -> RelationCheck:
    return RelationCheck(id=id, description=description, left=left[0], right=right[0], changed=left[0] != right[0],
                         evidence=f"{labels[0]}: {left[1]} | {labels[1]}: {right[1]}")


def _contact_made(m: ContactMetrics) -> tuple[bool, str]:
    if m.first_contact_time is None:
        return False, "no contact reported"
    return True, f"first contact at t={m.first_contact_time:.2f} s, {m.contact_samples} samples in contact"


def _not_through(m: ContactMetrics) -> tuple[bool, str]:
    return not m.passed_through, f"lowest centre z={m.min_z:.5f} m" + (" (PASSED THROUGH)" if m.passed_through else "")


def _stopped(m: LaneMetrics) -> tuple[bool, str]:
    return m.stop.stopped, (f"stopped at t={m.stop.time:.2f} s after {m.stop.distance:.4f} m" if m.stop.stopped
                            else m.stop.detail)


def _slides(m: LaneMetrics) -> tuple[bool, str]:
    return not m.tumbled, f"max tilt {m.max_tilt_deg:.1f} deg" + (" (TUMBLED)" if m.tumbled else "")


def low_lane_farther(friction: FrictionMetrics, tol: float) -> tuple[bool | None, str]:
    """Does the lane with the lower engine pair friction stop farther, beyond the grading resolution?"""
    low, high = lanes_by_pair(friction)
    if not (low.stop.stopped and high.stop.stopped):
        return None, f"a lane did not stop within the window ({low.lane}: {low.stop.detail}; {high.lane}: {high.stop.detail})"
    farther = direction(low.stop.distance - high.stop.distance, tol, down="high", up="low")
    return farther == "low", (f"{low.lane} (pair {low.pair_friction:g}) {low.stop.distance:.4f} m, {high.lane} "
                              f"(pair {high.pair_friction:g}) {high.stop.distance:.4f} m: farther "
                              f"{farther or 'unresolved within ' + format(tol, 'g') + ' m'}")


def case_relations(left: CaseResult, right: CaseResult, rubric: Rubric | None = None) -> list[RelationCheck]:
    """The single-case relations: contact made and not passed through; each lane stopped; the low lane farther."""
    labels = (side_label(left), side_label(right))
    ml, mr = left.metrics, right.metrics
    if isinstance(ml, ContactMetrics):
        return [
            _relation("contact_made", "the cube contacts the table", _contact_made(ml), _contact_made(mr), labels),
            _relation("not_passed_through", "the cube does not pass through the table", _not_through(ml),
                      _not_through(mr), labels),
        ]
    checks = [_relation(f"stopped.{lane}", f"lane {lane} stops (sustained) within the measured window",
                        _stopped(ml.lane(lane)), _stopped(mr.lane(lane)), labels) for lane in ml.lanes]
    checks += [_relation(f"slides.{lane}", f"lane {lane}'s cube slides without tumbling (rubric.metrics tumble rule)",
                         _slides(ml.lane(lane)), _slides(mr.lane(lane)), labels) for lane in ml.lanes
               if ml.lane(lane).tumbled is not None and mr.lane(lane).tumbled is not None]
    if len(ml.lanes) > 1:
        tol = (rubric or load_rubric("L03")).tolerances["stop_distance_resolution"].value
        checks.append(_relation("low_lane_farther", "the lane with the lower pair friction travels farther before "
                                "its sustained stop", low_lane_farther(ml, tol), low_lane_farther(mr, tol), labels))
    return checks


# --- one case, both measurements -----------------------------------------------------------------------------

def classify(arrays: list[ArrayDiff], metrics: list[MetricDiff], relations: list[RelationCheck],
             same_axis: bool) -> Classification:
    if any(r.changed for r in relations):
        return "relation_changed"
    if not all(a.within for a in arrays) or not all(m.within for m in metrics):
        return "numeric_drift"
    if same_axis and all(a.bit_equal for a in arrays) and all(m.left == m.right for m in metrics):
        return "identical"
    return "within_tolerance"


def compare_cases(left: CaseResult, right: CaseResult, tolerances: AuditTolerances | None = None, *,
                  rubric: Rubric | None = None) -> CaseComparison:
    """Compare two measurements of one case spec; ValueError (naming the field) for different specs or failed runs."""
    _check_comparable(left, right)
    tolerances = tolerances or load_audit_tolerances()
    arrays = array_diffs(left, right, tolerances)
    metrics = metric_diffs(left, right, tolerances)
    relations = case_relations(left, right, rubric)
    shared = len(shared_indices(left, right)[0])
    same_axis = shared == len(left.arrays["t"]) == len(right.arrays["t"])
    classification = classify(arrays, metrics, relations, same_axis)
    comparison = CaseComparison(
        case=left.spec.name, axes=_axes(left, right), left=side_label(left), right=side_label(right),
        shared_times=shared, arrays=arrays, metrics=metrics, relations=relations, classification=classification,
        tolerances_version=tolerances.label, summary="")
    return comparison.model_copy(update={"summary": summarize(comparison)})


def _show(value: Value) -> str:
    return f"{value:.6g}" if isinstance(value, float) else str(value)


def summarize(c: CaseComparison) -> str:
    head = f"{c.case}: {c.classification} ({c.left} vs {c.right}, {c.shared_times} shared sample times, {c.tolerances_version})"
    parts = [head]
    changed = [r for r in c.relations if r.changed]
    if changed:
        parts.append("relations changed: " + "; ".join(f"{r.id} {r.left} -> {r.right}" for r in changed))
    over = [f"{a.name} max {a.max_abs:.3g} {a.unit} > {a.tolerance_value:g}" if a.max_abs is not None
            else f"{a.name}: no shared sample times" for a in c.arrays if not a.within]
    over += [f"{m.name} {_show(m.left)} vs {_show(m.right)}"
             + (f" (|diff| {m.abs_diff:.3g} {m.unit} > {m.tolerance})" if m.abs_diff is not None else "")
             for m in c.metrics if not m.within]
    if over:
        parts.append("beyond tolerance: " + "; ".join(over))
    if c.classification == "within_tolerance":
        worst = max(c.arrays, key=lambda a: a.max_abs / a.tolerance_value if a.tolerance_value else 0.0, default=None)
        if worst is not None:
            parts.append(f"largest array difference relative to its tolerance: {worst.name} max {worst.max_abs:.3g} "
                         f"{worst.unit} (tolerance {worst.tolerance_value:g})")
    return "; ".join(parts)


# --- the lesson's relations between cases, on each side -----------------------------------------------------

BASELINE, TABLE_030 = "friction-baseline", "friction-table-0.30"


def _measured(results: Mapping[str, CaseResult], names: tuple[str, ...]) -> bool:
    return all(n in results and results[n].ok and results[n].arrays for n in names)


def _proxy_lowered(results, coarse: str, fine: str, tol: float) -> tuple[bool | None, str]:
    change = proxy_change(results[coarse].metrics, results[fine].metrics, tol)
    return (change.direction == "decrease" if change.valid else None), change.describe()


def _n1_n4(results, dz: float, dvz: float) -> tuple[bool, str]:
    al = align("N1", results["N1"].arrays, "N4", results["N4"].arrays)
    return cases_agree(al, dz_tol=dz, dvz_tol=dvz), (
        f"{al.shared_samples} shared times, max |dz| {al.max_abs_diff['z']:.3e} m (<= {dz:g}), "
        f"max |dvz| {al.max_abs_diff['vz']:.3e} m/s (<= {dvz:g})")


def _table_change(results, lane_role: str, rubric: Rubric) -> tuple[bool | None, str]:
    base, modified = results[BASELINE].metrics, results[TABLE_030].metrics
    low, high = lanes_by_pair(base)
    lane = (low if lane_role == "low" else high).lane
    before, after = base.lane(lane), modified.lane(lane)
    delta = stop_change(before, after)
    if delta is None:
        return None, f"{lane}: not stopped within the window in one run ({before.stop.detail}; {after.stop.detail})"
    if lane_role == "high":
        tol = rubric.tolerances["high_lane_unchanged"].value
        return abs(delta) <= tol, f"{lane}: stop distance {delta:+.4f} m (unchanged within {tol:g} m?)"
    tol = rubric.tolerances["stop_distance_resolution"].value
    return direction(delta, tol, down="shorter", up="farther") == "farther", (
        f"{lane}: stop distance {delta:+.4f} m (farther beyond {tol:g} m?)")


def compare_relations(left: Mapping[str, CaseResult], right: Mapping[str, CaseResult], *,
                      rubric: Rubric | None = None) -> list[RelationCheck]:
    """The lesson's relations between cases, judged on each side where both sides measured the cases they need.

    Every case both sides hold must be the same spec apart from backend and precision (ValueError otherwise).
    """
    for name in sorted(set(left) & set(right)):
        if left[name].ok and right[name].ok:
            _check_comparable(left[name], right[name])
    rubric = rubric or load_rubric("L03")
    tol = {name: t.value for name, t in rubric.tolerances.items()}
    labels = tuple(_side_labels(side) for side in (left, right))
    rules = [
        ("substeps_lower_proxy.N1_N2", "at dt=0.01 s, 2 substeps lower the penetration proxy (N1 -> N2)", ("N1", "N2"),
         lambda r: _proxy_lowered(r, "N1", "N2", tol["proxy_resolution"])),
        ("substeps_lower_proxy.N3_N4", "at dt=0.02 s, 2 substeps lower the penetration proxy (N3 -> N4)", ("N3", "N4"),
         lambda r: _proxy_lowered(r, "N3", "N4", tol["proxy_resolution"])),
        ("n1_n4_agree", "N1 and N4 agree at their shared sample times", ("N1", "N4"),
         lambda r: _n1_n4(r, tol["n1_n4_max_dz"], tol["n1_n4_max_dvz"])),
        ("baseline_low_lane_farther", "in the baseline run, the low-pair-friction lane travels farther", (BASELINE,),
         lambda r: low_lane_farther(r[BASELINE].metrics, tol["stop_distance_resolution"])),
        ("table_change_low_lane_farther", "lowering table friction to 0.30 makes the low lane travel farther",
         (BASELINE, TABLE_030), lambda r: _table_change(r, "low", rubric)),
        ("table_change_high_lane_unchanged", "lowering table friction leaves the high lane nearly unchanged",
         (BASELINE, TABLE_030), lambda r: _table_change(r, "high", rubric)),
    ]
    return [_relation(id, description, judge(left), judge(right), labels)
            for id, description, needs, judge in rules if _measured(left, needs) and _measured(right, needs)]


def _side_labels(results: Mapping[str, CaseResult]) -> str:
    labels = sorted({side_label(r) for r in results.values() if r.ok})
    return ", ".join(labels) or "no measured case"


__all__ = ["ArrayDiff", "AuditTolerances", "CaseComparison", "MetricDiff", "RelationCheck", "audit_versions",
           "case_relations", "classify", "compare_cases", "compare_relations", "load_audit_tolerances", "side_label"]
