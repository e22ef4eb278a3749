"""Tolerance review against measurements: which measured quantity each rubric tolerance judges, and whether a
tolerance is narrower than the spread of that quantity between backends or precisions.

A tolerance decides a verdict from a measured quantity (a direction of change, an agreement, a match). When two
measurements of ONE case that differ only in backend or precision already differ in that quantity by more than the
tolerance, a student's verdict can flip with the backend their run landed on: the review flags it and names the
comparisons that show it. Pure functions over plain data (stored metrics as JSON, audit comparisons as JSON), so the
same review runs in a notebook.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence

from pydantic import BaseModel, ConfigDict

from .rubrics import Rubric, Tolerance

# The axes whose spread can flag a tolerance; an execution-mode-only difference is shown, never flagged (the lesson
# contract says warm and isolated must agree, and a difference there is a runner bug, not a tolerance question).
FLAG_AXES = ("backend", "precision")


class Judged(BaseModel):
    """The measured quantity a tolerance judges: `quantities` in the audit's names ("contact.penetration_proxy",
    "lane.stop_distance", "contact.z" for an array), and how the scoring reads it."""

    model_config = ConfigDict(frozen=True)

    quantities: tuple[str, ...]
    reads: str


# From rubric/scoring/* and rubric/check.py: every `ctx.tol(name)` / `tolerances[name]` and what it is compared with.
JUDGED: dict[str, Judged] = {
    "proxy_resolution": Judged(
        quantities=("contact.penetration_proxy", "contact.tail_settling_error"),
        reads="the change of a contact case's penetration proxy (and tail settling error) between two cases is read "
              "as a direction (A2, X2, X3)"),
    "n1_n4_max_dz": Judged(
        quantities=("contact.z",),
        reads="N1 and N4 agree when their centre heights differ by at most this at every shared sample time (A3)"),
    "n1_n4_max_dvz": Judged(
        quantities=("contact.vz",),
        reads="N1 and N4 agree when their vertical velocities differ by at most this at every shared sample time "
              "(A3, lab check)"),
    "stop_distance_resolution": Judged(
        quantities=("lane.stop_distance",),
        reads="the difference of two sustained-stop distances is read as a direction (B2, B4, C7, H2)"),
    "high_lane_unchanged": Judged(
        quantities=("lane.stop_distance",),
        reads="the control lane's stop distance change within this counts as unchanged (B3, H3)"),
    "reported_stop_distance": Judged(
        quantities=("lane.stop_distance",),
        reads="a student's reported stop distance must match the measured one within this (H4)"),
    "pair_friction_abs": Judged(
        quantities=("lane.pair_friction",),
        reads="a stated pair friction must match the engine's contact friction within this (B1, C5, C6, H1)"),
    "initial_speed_match": Judged(
        quantities=("lane.initial_vx",),
        reads="each lane must start measurement at the declared speed within this (lab check)"),
    "separation_samples_resolution": Judged(
        quantities=("contact.separation_samples", "contact.contact_samples"),
        reads="a change of a count of samples (geometric separation, contact presence) beyond this is a direction "
              "(X2)"),
    "upward_speed_resolution": Judged(
        quantities=("contact.max_upward_velocity_after_contact",),
        reads="a change of the largest upward velocity after first contact beyond this is a direction (X2)"),
    "computed_relative": Judged(
        quantities=(),
        reads="a student's hand computation against the engine's reported discretization (C1, X1): counts and "
              "timesteps the engine reports exactly, with no measured spread"),
}


class Spread(BaseModel):
    """One quantity over the course's stored measurements of one case spec (its variants: backend, precision)."""

    case: str
    quantity: str  # "contact.penetration_proxy", or "lane.stop_distance [low]"
    n: int
    min: float
    max: float
    case_run_ids: list[int]
    variants: list[str]

    @property
    def spread(self) -> float:
        return self.max - self.min


class StoredValue(BaseModel):
    """One stored measurement's value of a quantity (a case run's metrics), with what produced it."""

    case: str
    spec_key: str
    case_run_id: int
    variant: str  # "cpu/32/warm": the backend that produced the number, always with it
    quantity: str
    lane: str | None = None
    value: float


class Difference(BaseModel):
    """One quantity's difference in one audit entry (two measurements of one case); `abs_diff` None: the quantity
    exists on one side only (a lane stopped on one backend and not the other), which no tolerance absorbs."""

    entry_id: int
    case: str
    left_variant: str
    right_variant: str
    axes: list[str]
    quantity: str
    name: str  # as the comparison names it: "penetration_proxy", "low.stop_distance", "z"
    abs_diff: float | None
    detail: str

    @property
    def flags(self) -> bool:
        return any(axis in FLAG_AXES for axis in self.axes)

    def exceeds(self, value: float) -> bool:
        return self.abs_diff is None or self.abs_diff > value


class ToleranceReview(BaseModel):
    """One tolerance of a version beside the measured spread of what it judges, and whether it is flagged."""

    name: str
    value: float
    unit: str
    rationale: str
    reviewer: str
    review_date: str
    items: list[str]
    reads: str | None  # None: the review does not know which quantity this tolerance judges
    quantities: list[str]
    stored: list[Spread]  # widest first
    audit: list[Difference]  # every difference of a judged quantity, largest first (None: one-sided, first)
    flagged: bool
    flag_entries: list[int]  # the audit entries whose cross-backend/precision difference exceeds the value
    reasons: list[str]

    @property
    def widest_stored(self) -> Spread | None:
        return self.stored[0] if self.stored else None

    @property
    def largest_audit(self) -> Difference | None:
        return self.audit[0] if self.audit else None


def variant_axes(left: str, right: str) -> list[str]:
    """Which of backend, precision, mode differ between two "backend/precision/mode" variants."""
    a, b = left.split("/"), right.split("/")
    return [axis for axis, x, y in zip(("backend", "precision", "mode"), a, b) if x != y]


# --- what stored metrics hold of a quantity -----------------------------------------------------------------------

def _lane_field(lane: Mapping, field: str) -> float | None:
    if field in ("stop_distance", "stop_time"):
        stop = lane.get("stop") or {}
        return stop.get("distance" if field == "stop_distance" else "time")
    value = lane.get(field)
    return None if isinstance(value, bool) else value


def stored_values(metrics: Mapping, quantity: str) -> list[tuple[str | None, float]]:
    """(lane or None, value) of a quantity in one run's stored metrics (rubric.metrics JSON); arrays and absent values
    (not stopped, no contact) give nothing: a stored metric has no array."""
    scope, _, field = quantity.partition(".")
    if scope == "contact" and metrics.get("kind") == "contact":
        value = metrics.get(field)
        return [] if value is None or isinstance(value, bool) else [(None, float(value))]
    if scope == "lane" and metrics.get("kind") == "friction":
        found = [(name, _lane_field(lane, field)) for name, lane in sorted((metrics.get("lanes") or {}).items())]
        return [(name, float(v)) for name, v in found if v is not None]
    return []


def spreads(values: Iterable[StoredValue]) -> list[Spread]:
    """Values grouped by case spec, quantity and lane: min, max, n and the runs behind each; widest first."""
    groups: dict[tuple, list[StoredValue]] = {}
    for v in values:
        groups.setdefault((v.spec_key, v.quantity, v.lane), []).append(v)
    out = []
    for (_, quantity, lane), members in groups.items():
        numbers = [m.value for m in members]
        out.append(Spread(case=members[0].case, quantity=quantity + (f" [{lane}]" if lane else ""), n=len(members),
                          min=min(numbers), max=max(numbers), case_run_ids=sorted(m.case_run_id for m in members),
                          variants=sorted({m.variant for m in members})))
    return sorted(out, key=lambda s: (-s.spread, s.case, s.quantity))


# --- what an audit comparison says of a quantity ------------------------------------------------------------------

def _quantity_of(name: str, kind: str, lanes: Sequence[str], *, array: bool) -> str | None:
    """The audit quantity key of a compared array or metric: "z" -> contact.z, "low.stop_distance" and "low_x" ->
    lane.stop_distance and lane.x."""
    if kind == "contact":
        return f"contact.{name}"
    for lane in lanes:
        prefix = f"{lane}_" if array else f"{lane}."
        if name.startswith(prefix):
            return f"lane.{name[len(prefix):]}"
    return None


def comparison_differences(entry_id: int, case: str, left_variant: str, right_variant: str, kind: str,
                           lanes: Sequence[str], comparison: Mapping) -> list[Difference]:
    """Every array and numeric metric difference of one stored audit comparison (rubric.discrepancy JSON)."""
    axes = variant_axes(left_variant, right_variant)
    base = dict(entry_id=entry_id, case=case, left_variant=left_variant, right_variant=right_variant, axes=axes)
    out = []
    for a in comparison.get("arrays") or []:
        quantity = _quantity_of(a["name"], kind, lanes, array=True)
        if quantity is not None and a.get("max_abs") is not None:
            out.append(Difference(**base, quantity=quantity, name=a["name"], abs_diff=a["max_abs"],
                                  detail=f"array {a['name']}: max |diff| {a['max_abs']:.3g} {a.get('unit', '')} over "
                                         f"{a.get('shared_samples')} shared sample times"))
    for m in comparison.get("metrics") or []:
        quantity = _quantity_of(m["name"], kind, lanes, array=False)
        left, right = m.get("left"), m.get("right")
        if quantity is None or isinstance(left, bool) or isinstance(right, bool) or (left is None and right is None):
            continue
        one_sided = left is None or right is None
        out.append(Difference(**base, quantity=quantity, name=m["name"],
                              abs_diff=None if one_sided else abs(float(left) - float(right)),
                              detail=f"{m['name']}: {_show(left)} vs {_show(right)} {m.get('unit', '')}".rstrip()))
    return out


def _show(value) -> str:
    return "absent" if value is None else f"{value:.6g}" if isinstance(value, float) else str(value)


def _largest_first(d: Difference) -> tuple:
    return (d.abs_diff is not None, -(d.abs_diff or 0.0), d.entry_id)


# --- the review -------------------------------------------------------------------------------------------------

def review_tolerance(name: str, tolerance: Tolerance, items: list[str], stored: Iterable[StoredValue],
                     differences: Iterable[Difference]) -> ToleranceReview:
    """One tolerance beside the spread of what it judges; flagged when a cross-backend or cross-precision difference
    of a judged quantity in the audit log exceeds it (or exists on one side only)."""
    judged = JUDGED.get(name)
    quantities = list(judged.quantities) if judged else []
    mine = sorted((d for d in differences if d.quantity in quantities), key=_largest_first)
    over = [d for d in mine if d.flags and d.exceeds(tolerance.value)]
    reasons = [f"audit entry {d.entry_id} ({d.case}, {d.left_variant} vs {d.right_variant}): {d.detail} "
               + ("exists on one side only" if d.abs_diff is None else f"> {tolerance.value:g} {tolerance.unit}")
               for d in over]
    if judged is None:
        reasons.append(f"which measured quantity {name} judges is not known to the review (rubric.tolerance_review."
                       "JUDGED); it is shown without measurements")
    return ToleranceReview(
        name=name, value=tolerance.value, unit=tolerance.unit, rationale=tolerance.rationale,
        reviewer=tolerance.reviewer, review_date=tolerance.review_date.isoformat(), items=items,
        reads=judged.reads if judged else None, quantities=quantities,
        stored=spreads(v for v in stored if v.quantity in quantities), audit=mine, flagged=bool(over),
        flag_entries=sorted({d.entry_id for d in over}), reasons=reasons)


def items_using(rubric: Rubric) -> dict[str, list[str]]:
    """Tolerance name -> the ids of the items that declare it."""
    used: dict[str, list[str]] = {name: [] for name in rubric.tolerances}
    for item in rubric.items:
        for name in item.tolerances:
            used.setdefault(name, []).append(item.id)
    return used


def review_rubric(rubric: Rubric, stored: Sequence[StoredValue],
                  differences: Sequence[Difference]) -> list[ToleranceReview]:
    """Every tolerance of a version reviewed, flagged ones first, then in the version's own order."""
    used = items_using(rubric)
    reviews = [review_tolerance(name, tol, used.get(name, []), stored, differences)
               for name, tol in rubric.tolerances.items()]
    order = {name: n for n, name in enumerate(rubric.tolerances)}
    return sorted(reviews, key=lambda r: (not r.flagged, order[r.name]))


__all__ = ["Difference", "FLAG_AXES", "JUDGED", "Judged", "Spread", "StoredValue", "ToleranceReview",
           "comparison_differences", "items_using", "review_rubric", "review_tolerance", "spreads", "stored_values",
           "variant_axes"]
