"""Part B items (friction and sustained stopping distance): pair values, farther lane, control lane, colour."""

from __future__ import annotations

from ..cases import COLOR_SWAP
from ..metrics import LaneMetrics
from ..relations import ColorEffect, color_effect, direction, stop_change
from ..rubrics import Item
from .scorer import Context, NotMeasured, Outcome, credit, relation_verdict, scoring_rule

BASELINE = "friction-baseline"


def pair_of(ctx: Context, role: str, lane: LaneMetrics) -> float:
    """The pair friction the engine used for a lane (read from its contact data); a lane never in contact has none."""
    if lane.pair_friction is None:
        raise NotMeasured(f"{ctx.run_name(role)}/{lane.lane}: no cube-table contact was reported, so the engine "
                          "assigned no pair friction")
    return lane.pair_friction


def engine_pairs(ctx: Context, role: str) -> dict[str, float]:
    """Lane -> the pair friction the engine used in that run."""
    return {name: pair_of(ctx, role, m) for name, m in ctx.friction(role).lanes.items()}


def pair_disagreements(ctx: Context, *roles: str) -> list[str]:
    """Lanes where the engine's contact friction and the Python copy of its rule differ: shown, never hidden."""
    out = []
    for role in roles:
        for lane, m in ctx.friction(role).lanes.items():
            if not m.pair_friction_agrees:
                out.append(f"{ctx.run_name(role)}/{lane}: engine {m.pair_friction_values} vs rule {m.pair_friction_rule:g}")
    return out


def with_disagreements(text: str, ctx: Context, *roles: str) -> str:
    bad = pair_disagreements(ctx, *roles)
    return text + ("; ENGINE AND PAIR RULE DISAGREE: " + "; ".join(bad) if bad else "; the engine agrees with the "
                   "max rule of rubric/friction.py")


@scoring_rule("pair_value_changes", reads=(BASELINE, "table_exercise"))
def pair_value_changes(ctx: Context, item: Item, a) -> Outcome:
    tol = ctx.tol("pair_friction_abs")
    before, after = engine_pairs(ctx, BASELINE), engine_pairs(ctx, "table_exercise")
    changed = sorted(lane for lane in before if abs(after[lane] - before[lane]) > tol)
    measured = "engine pair friction " + ", ".join(f"{lane} {before[lane]:g} -> {after[lane]:g}" for lane in before)
    return Outcome(credit(sorted(a.lanes) == changed), f"lanes {changed}",
                   with_disagreements(measured, ctx, BASELINE, "table_exercise"),
                   {f"{lane}_pair_baseline": before[lane] for lane in before}
                   | {f"{lane}_pair_modified": after[lane] for lane in before},
                   ctx.backends(BASELINE, "table_exercise"))


@scoring_rule("lane_travels_farther", reads=(BASELINE,))
def lane_travels_farther(ctx: Context, item: Item, a) -> Outcome:
    low, high = ctx.lane(BASELINE, "low"), ctx.lane(BASELINE, "high")
    evidence = {"low_stop_distance_m": low.stop.distance, "high_stop_distance_m": high.stop.distance,
                "low_stop_time_s": low.stop.time, "high_stop_time_s": high.stop.time,
                "low_pair": low.pair_friction, "high_pair": high.pair_friction}
    backends = ctx.backends(BASELINE)
    if not (low.stop.stopped and high.stop.stopped):
        return Outcome("inconclusive", "the lane with the longer sustained-stop distance",
                       f"low: {low.stop.detail}; high: {high.stop.detail}", evidence, backends)
    farther = direction(low.stop.distance - high.stop.distance, ctx.tol("stop_distance_resolution"),
                        down="high", up="low")
    measured = (f"stop distance low {low.stop.distance:.4f} m (pair {low.pair_friction:g}, stopped at "
                f"{low.stop.time:.2f} s), high {high.stop.distance:.4f} m (pair {high.pair_friction:g}, stopped at "
                f"{high.stop.time:.2f} s); stop time and distance need not rank alike")
    return Outcome(relation_verdict(a.lane, [farther]), f"the lane measured farther ({farther or 'unresolved'})",
                   measured, evidence, backends)


def lane_changes(ctx: Context) -> tuple[dict[str, float | None], dict, dict]:
    """Per lane, the change of sustained-stop distance from the baseline run to the student's table exercise."""
    base, modified = ctx.friction(BASELINE), ctx.friction("table_exercise")
    deltas = {lane: stop_change(m, modified.lane(lane)) for lane, m in base.lanes.items()}
    evidence = {}
    for lane, m in base.lanes.items():
        evidence |= {f"{lane}_baseline_m": m.stop.distance, f"{lane}_modified_m": modified.lane(lane).stop.distance,
                     f"{lane}_delta_m": deltas[lane]}
    return deltas, evidence, ctx.backends(BASELINE, "table_exercise")


def describe_changes(deltas: dict, evidence: dict) -> str:
    return "; ".join(
        f"{lane}: {evidence[f'{lane}_baseline_m']} -> {evidence[f'{lane}_modified_m']} m (a lane did not stop "
        f"within the window)" if d is None else
        f"{lane}: {evidence[f'{lane}_baseline_m']:.4f} -> {evidence[f'{lane}_modified_m']:.4f} m (delta {d:+.4f} m)"
        for lane, d in deltas.items())


@scoring_rule("lane_unchanged", reads=(BASELINE, "table_exercise"))
def lane_unchanged(ctx: Context, item: Item, a) -> Outcome:
    deltas, evidence, backends = lane_changes(ctx)
    if any(d is None for d in deltas.values()):
        return Outcome("inconclusive", "lanes whose stop distance changes within tolerance",
                       describe_changes(deltas, evidence), evidence, backends)
    tol = ctx.tol("high_lane_unchanged")
    unchanged = sorted(lane for lane, d in deltas.items() if abs(d) <= tol)
    word = {0: "neither", 2: "both"}.get(len(unchanged)) or unchanged[0]
    return Outcome(credit(a.lane == word), word, describe_changes(deltas, evidence), evidence, backends)


def measured_color_effect(ctx: Context) -> tuple[ColorEffect, dict[str, float | None], dict[str, str]]:
    """The baseline run against its colour-swapped twin: the lesson's claim that colour is visual, measured."""
    base, swapped = ctx.result(BASELINE), ctx.result(COLOR_SWAP)
    colors = {lane.name: lane.color for lane in swapped.spec.lanes}
    effect = color_effect(base.metrics, swapped.metrics, base.arrays, swapped.arrays, colors,
                          tol=ctx.tol("stop_distance_resolution"))
    evidence = {"arrays_identical": int(effect.identical)} | {f"{lane}_stop_delta_m": d
                                                               for lane, d in effect.stop_deltas.items()}
    return effect, evidence, ctx.backends(BASELINE, COLOR_SWAP)


@scoring_rule("color_layer", reads=(BASELINE, COLOR_SWAP))
def color_layer(ctx: Context, item: Item, a) -> Outcome:
    effect, evidence, backends = measured_color_effect(ctx)
    ok = a.color_layer == "visual" and a.affects_results is effect.affects_results
    return Outcome(credit(ok), f"visual layer; affects results: {str(effect.affects_results).lower()}",
                   f"{BASELINE} re-run with the lane colours swapped: {effect.describe()}", evidence, backends)
