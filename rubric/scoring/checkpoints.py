"""Concept checkpoint items C1-C8: timing, equal duration, shared times, zero contact, pair rule, colour, stopping."""

from __future__ import annotations

import numpy as np

from ..cases import COLOR_SWAP
from ..metrics import align, separation_mask
from ..rubrics import Item
from .scorer import Context, NotMeasured, Outcome, credit, scoring_rule
from .part_b import BASELINE, measured_color_effect, pair_disagreements, pair_of

_RULES = {"max": max, "min": min, "mean": lambda a, b: (a + b) / 2, "product": lambda a, b: a * b}


def timing_outcome(ctx: Context, role: str, a) -> Outcome:
    """substep_dt, outer samples and internal updates as the engine reported them for a run (its provenance)."""
    result = ctx.result(role)
    d = result.provenance.discretization
    rel = ctx.tol("computed_relative")
    ok = (abs(a.substep_dt.si - d.substep_dt) <= rel * d.substep_dt and a.samples == d.sample_count
          and a.internal_updates == d.internal_updates)
    return Outcome(credit(ok),
                   f"substep_dt {d.substep_dt:g} s, {d.sample_count} samples, {d.internal_updates} internal updates",
                   f"reported by the engine for {ctx.run_name(role)}: dt {d.dt:g} s, substeps {d.substeps}, "
                   f"{d.n_steps} outer steps over {d.duration:g} s",
                   {"substep_dt_s": d.substep_dt, "samples": d.sample_count, "internal_updates": d.internal_updates},
                   ctx.backends(role))


@scoring_rule("timing_n4", reads=("N4",))
def timing_n4(ctx: Context, item: Item, a) -> Outcome:
    return timing_outcome(ctx, "N4", a)


@scoring_rule("equal_steps_invalid", reads=())
def equal_steps_invalid(ctx: Context, item: Item, a) -> Outcome:
    n1, n3 = ctx.cases["N1"], ctx.cases["N3"]
    covered = n1.n_steps * n3.dt
    return Outcome(credit(a.reason == "unequal_simulated_duration"), "unequal_simulated_duration",
                   f"{n1.n_steps} steps cover {n1.n_steps * n1.dt:g} s at dt {n1.dt:g} but {covered:g} s at dt {n3.dt:g}",
                   {"steps": n1.n_steps, "duration_at_dt_0.01_s": n1.n_steps * n1.dt, "duration_at_dt_0.02_s": covered})


@scoring_rule("shared_times", reads=("N1", "N4"))
def shared_times(ctx: Context, item: Item, a) -> Outcome:
    measured, evidence, backends = "", {}, {}
    r1, r4 = ctx.maybe(ctx.result, "N1"), ctx.maybe(ctx.result, "N4")
    if r1 and r4:
        al = align("N1", r1.arrays, "N4", r4.arrays)
        measured = f"N1 {al.samples_a} samples, N4 {al.samples_b}; only {al.shared_samples} times are shared"
        evidence = {"N1_samples": al.samples_a, "N4_samples": al.samples_b, "shared_samples": al.shared_samples}
        backends = ctx.backends("N1", "N4")
    return Outcome(credit(a.reason == "unshared_samples_have_no_counterpart"), "unshared_samples_have_no_counterpart",
                   measured, evidence, backends)


@scoring_rule("zero_contact", reads=("N1", "N2", "N3", "N4"))
def zero_contact(ctx: Context, item: Item, a) -> Outcome:
    evidence, backends = {}, {}
    for role in ("N1", "N2", "N3", "N4"):
        r = ctx.maybe(ctx.result, role)
        if r is None or r.metrics.first_contact_index is None:
            continue
        after = slice(r.metrics.first_contact_index, None)
        zero = r.arrays["contact_count"][after] == 0
        # Zero contacts without observed separation: no geometric evidence of a rebound at those samples.
        unsupported = zero & ~separation_mask(r.spec, r.arrays)[after]
        evidence[f"{role}_zero_contact_samples"] = int(zero.sum())
        evidence[f"{role}_zero_contact_without_separation"] = int(unsupported.sum())
        backends[ctx.run_name(role)] = r.backend
    measured = ", ".join(f"{k} {v}" for k, v in evidence.items()) or "no measured contact case available"
    return Outcome(credit(a.proves_rebound is False), "no: also require clearance above tolerance",
                   measured, evidence, backends)


@scoring_rule("pair_value_low", reads=(BASELINE,))
def pair_value_low(ctx: Context, item: Item, a) -> Outcome:
    lanes = ctx.friction(BASELINE).lanes
    # The question's pair (the lesson's table 0.50 with the cube of friction 0.10, or the student's variant's table
    # and low-lane values), found by the engine's own per-side values.
    table, cube = ctx.parameters["table_friction"], ctx.parameters["low_lane_friction"]
    lane = next((m for m in lanes.values() if np.isclose(m.table_friction, table) and np.isclose(m.cube_friction, cube)),
                None)
    if lane is None:
        raise NotMeasured(f"no lane of {ctx.run_name(BASELINE)} ran with table friction {table:g} and cube friction "
                          f"{cube:g}: " + ", ".join(f"{m.lane} ({m.table_friction:g}, {m.cube_friction:g})"
                                                     for m in lanes.values()))
    ok = abs(a.pair_friction - pair_of(ctx, BASELINE, lane)) <= ctx.tol("pair_friction_abs")
    measured = (f"the engine's contact friction for lane '{lane.lane}' (table {lane.table_friction:g}, cube "
                f"{lane.cube_friction:g}) in {BASELINE}: {lane.pair_friction:g}")
    bad = pair_disagreements(ctx, BASELINE)
    return Outcome(credit(ok), f"{lane.pair_friction:g}", measured + ("; DISAGREES WITH THE RULE: " + "; ".join(bad)
                                                                       if bad else ""),
                   {"pair_friction": lane.pair_friction}, ctx.backends(BASELINE))


@scoring_rule("pair_rule", reads=(BASELINE, COLOR_SWAP, "table_exercise"))
def pair_rule(ctx: Context, item: Item, a) -> Outcome:
    """The student's rule must reproduce every pair value the engine used in every measured friction run."""
    tol, rule = ctx.tol("pair_friction_abs"), _RULES[a.pair_rule]
    roles = [BASELINE, COLOR_SWAP] + (["table_exercise"] if ctx.maybe(ctx.result, "table_exercise") else [])
    rows, ok = [], True
    for role in roles:
        for m in ctx.friction(role).lanes.values():
            predicted = rule(m.table_friction, m.cube_friction)
            ok &= abs(predicted - pair_of(ctx, role, m)) <= tol
            rows.append(f"{ctx.run_name(role)}/{m.lane} ({m.table_friction:g}, {m.cube_friction:g}) -> engine "
                        f"{m.pair_friction:g}, {a.pair_rule} gives {predicted:g}")
    # The expected rule is the one that reproduces the engine, not a constant.
    fits = [name for name, fn in _RULES.items()
            if all(abs(fn(m.table_friction, m.cube_friction) - m.pair_friction) <= tol
                   for role in roles for m in ctx.friction(role).lanes.values())]
    return Outcome(credit(ok), " or ".join(fits) or "no listed rule fits the engine",
                   "; ".join(rows), {}, ctx.backends(*roles))


@scoring_rule("color_swap", reads=(BASELINE, COLOR_SWAP))
def color_swap(ctx: Context, item: Item, a) -> Outcome:
    effect, evidence, backends = measured_color_effect(ctx)
    if not effect.affects_results:
        expected = "none"
    else:
        colors = set(effect.farther_color.values())
        expected = f"{colors.pop()}_slides_farther" if len(colors) == 1 else "a change that no answer names"
    return Outcome(credit(a.color_effect == expected), expected,
                   f"{BASELINE} re-run with the lane colours swapped: {effect.describe()}", evidence, backends)


@scoring_rule("one_sample_stop", reads=(BASELINE,))
def one_sample_stop(ctx: Context, item: Item, a) -> Outcome:
    parts, evidence, backends = [], {}, {}
    r = ctx.maybe(ctx.result, BASELINE)
    if r:
        for lane in r.spec.lanes:
            vx, t = r.arrays[f"{lane.name}_vx"], r.arrays["t"]
            below = np.flatnonzero(np.abs(vx) < r.spec.stop_speed)
            stop = r.metrics.lane(lane.name).stop
            first = float(t[below[0]]) if below.size else None
            early = int(np.sum(below < stop.index)) if stop.stopped else int(below.size)
            evidence |= {f"{lane.name}_first_below_threshold_s": first, f"{lane.name}_sustained_stop_s": stop.time,
                         f"{lane.name}_isolated_samples_before_stop": early}
            when = "never" if first is None else f"at {first:.2f} s"
            sustained = f"sustained stop at {stop.time:.2f} s" if stop.stopped else stop.detail
            parts.append(f"{lane.name}: first |vx| < {r.spec.stop_speed} {when}, {sustained}")
        backends = ctx.backends(BASELINE)
    return Outcome(credit(a.establishes_stop is False), "no: the hold interval must stay below threshold",
                   "; ".join(parts), evidence, backends)

