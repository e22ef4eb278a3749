"""Hands-on exercise items H1-H6 (table friction 0.50 -> 0.30) and extension items X1-X3 (dt=0.01, substeps=4)."""

from __future__ import annotations

import re

from ..metrics import ContactMetrics
from ..relations import direction, proxy_change
from ..rubrics import Item
from .checkpoints import timing_outcome
from .scorer import EVERY_RUN, Context, NotMeasured, Outcome, credit, relation_verdict, scoring_rule
from .part_b import BASELINE, describe_changes, engine_pairs, lane_changes, with_disagreements


@scoring_rule("exercise_pair_values", reads=(BASELINE, "table_exercise"))
def exercise_pair_values(ctx: Context, item: Item, a) -> Outcome:
    tol = ctx.tol("pair_friction_abs")
    want = {"baseline": engine_pairs(ctx, BASELINE), "modified": engine_pairs(ctx, "table_exercise")}
    ok = all(abs(getattr(getattr(a, run), lane) - want[run][lane]) <= tol for run in want for lane in ("low", "high"))
    shown = {run: {lane: round(v, 6) for lane, v in pairs.items()} for run, pairs in want.items()}
    return Outcome(credit(ok), str(shown),
                   with_disagreements(f"the engine's contact friction per lane in {BASELINE} and "
                                      f"{ctx.run_name('table_exercise')}", ctx, BASELINE, "table_exercise"),
                   {f"{run}_{lane}": v for run, pairs in want.items() for lane, v in pairs.items()},
                   ctx.backends(BASELINE, "table_exercise"))


@scoring_rule("low_lane_direction", reads=(BASELINE, "table_exercise"))
def low_lane_direction(ctx: Context, item: Item, a) -> Outcome:
    deltas, evidence, backends = lane_changes(ctx)
    d = deltas["low"]
    measured = None if d is None else direction(d, ctx.tol("stop_distance_resolution"), down="shorter", up="farther")
    return Outcome(relation_verdict(a.low, [measured]), f"measured {measured or 'unresolved'}",
                   describe_changes(deltas, evidence), evidence, backends)


@scoring_rule("high_lane_direction", reads=(BASELINE, "table_exercise"))
def high_lane_direction(ctx: Context, item: Item, a) -> Outcome:
    deltas, evidence, backends = lane_changes(ctx)
    d = deltas["high"]
    if d is None:
        return Outcome("inconclusive", "unchanged within tolerance", describe_changes(deltas, evidence),
                       evidence, backends)
    # The control lane: "unchanged" is itself the relation under test, decided by the reviewed margin.
    measured = direction(d, ctx.tol("high_lane_unchanged"), down="shorter", up="farther") or "unchanged"
    return Outcome(credit(a.high == measured), measured, describe_changes(deltas, evidence), evidence, backends)


@scoring_rule("reported_stops", reads=(BASELINE, "table_exercise"))
def reported_stops(ctx: Context, item: Item, a) -> Outcome:
    tol = ctx.tol("reported_stop_distance")
    ok, parts, evidence = True, [], {}
    for run, role in (("baseline", BASELINE), ("modified", "table_exercise")):
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
    return Outcome(credit(ok), "the measured sustained stops", "; ".join(parts), evidence,
                   ctx.backends(BASELINE, "table_exercise"))


@scoring_rule("exercise_one_factor", reads=())
def exercise_one_factor(ctx: Context, item: Item, a) -> Outcome:
    """Decided by the submitted config itself: the student's claim must match the field-by-field comparison."""
    finding = ctx.findings["table_exercise"]
    return Outcome(credit(a.only_table_friction_changed is finding.ok), str(finding.ok).lower(), finding.describe())


@scoring_rule("engine_version", reads=EVERY_RUN)
def engine_version(ctx: Context, item: Item, a) -> Outcome:
    """The version the student names must be the one recorded in the provenance of this submission's own runs."""
    recorded = {r.provenance.versions.get("genesis", "unknown") for r in ctx.results.values()
                if r.ok and r.provenance is not None}
    if not recorded:
        errors = sorted({r.error for r in ctx.results.values() if r.error})
        raise NotMeasured("no valid run of this submission recorded a Genesis version"
                          + (f": {errors[0]}" if errors else ""))
    found = [v for v in sorted(recorded) if re.search(rf"(?<![0-9.]){re.escape(v)}(?![0-9.])", a.engine_version)]
    ok = len(recorded) == 1 and bool(found)
    return Outcome(credit(ok), " and ".join(sorted(recorded)),
                   f"the provenance of this submission's {len(ctx.results)} runs records genesis-world "
                   + ", ".join(sorted(recorded)))


@scoring_rule("timing_extension", reads=("extension", "N1"))
def timing_extension(ctx: Context, item: Item, a) -> Outcome:
    out = timing_outcome(ctx, "extension", a)
    n1 = ctx.maybe(ctx.result, "N1")
    if n1 is not None:
        work = out.evidence["internal_updates"] / n1.provenance.discretization.internal_updates
        out.evidence["work_vs_N1"] = work
        out.measured += f"; {work:g}x the internal updates of N1"
        out.backends |= ctx.backends("N1")
    return out


def _zero_contact_after_first(m: ContactMetrics) -> int:
    return 0 if m.first_contact_index is None else m.n_samples - m.first_contact_index - m.contact_samples


def diagnostic_changes(ctx: Context, before: ContactMetrics, after: ContactMetrics) -> dict[str, tuple[str | None, str]]:
    """Per diagnostic of the lesson's evidence table: 'improved', 'worse', 'unchanged' or None (inside tolerance /
    not a number), each with the measured values, from the coarser case `before` to the finer case `after`."""
    samples = ctx.tol("separation_samples_resolution")
    proxy = proxy_change(before, after, ctx.tol("proxy_resolution"))
    tail = direction(abs(after.tail_settling_error) - abs(before.tail_settling_error), ctx.tol("proxy_resolution"),
                     down="improved", up="worse")
    up_b, up_a = before.max_upward_velocity_after_contact or 0.0, after.max_upward_velocity_after_contact or 0.0
    zero_b, zero_a = _zero_contact_after_first(before), _zero_contact_after_first(after)
    return {
        "penetration_proxy": ({"decrease": "improved", "increase": "worse"}.get(proxy.direction), proxy.describe()),
        "geometric_separation": (direction(after.separation_samples - before.separation_samples, samples,
                                           down="improved", up="worse"),
                                 f"separation samples {before.separation_samples} -> {after.separation_samples}"),
        "contact_presence": (direction(zero_a - zero_b, samples, down="improved", up="worse"),
                             f"samples without contact after first contact {zero_b} -> {zero_a}"),
        "upward_velocity": (direction(up_a - up_b, ctx.tol("upward_speed_resolution"), down="improved", up="worse"),
                            f"max upward vz after contact {up_b:.3f} -> {up_a:.3f} m/s"),
        "tail_settling_error": (tail, f"|tail settling error| {abs(before.tail_settling_error) * 1000:.3f} -> "
                                      f"{abs(after.tail_settling_error) * 1000:.3f} mm"),
        # Both runs passed validation, so both were finite throughout: nothing left to improve.
        "finite_state": ("unchanged", "both records finite"),
        "full_trajectory": (None, "a whole trajectory is not one number; read it in the figures"),
    }


@scoring_rule("may_improve", reads=("N1", "extension"))
def may_improve(ctx: Context, item: Item, a) -> Outcome:
    """Credit only for improvements the student's extension run measured against N1, each under its tolerance."""
    before, after = ctx.contact("N1"), ctx.contact("extension")
    changes = diagnostic_changes(ctx, before, after)
    improved = sorted(name for name, (verdict, _) in changes.items() if verdict == "improved")
    if a.may_improve:
        verdict = relation_verdict("improved", [changes[name][0] for name in a.may_improve])
    else:
        verdict = credit(not improved)
    measured = "; ".join(f"{name}: {what} ({v or 'inside tolerance'})" for name, (v, what) in changes.items())
    return Outcome(verdict, f"only diagnostics measured to improve: {improved or 'none'}",
                   f"N1 -> {ctx.run_name('extension')}: {measured}",
                   {f"{name}_improved": int(v == "improved") for name, (v, _) in changes.items()},
                   ctx.backends("N1", "extension"))


@scoring_rule("not_guaranteed", reads=("N1", "N2", "N3", "N4", "extension"))
def not_guaranteed(ctx: Context, item: Item, a) -> Outcome:
    tol = ctx.tol("proxy_resolution")
    worse, evidence, backends = [], {}, {}
    for fewer, more in (("N1", "N2"), ("N3", "N4"), ("N1", "extension")):
        m0, m1 = ctx.maybe(ctx.contact, fewer), ctx.maybe(ctx.contact, more)
        if m0 is None or m1 is None:
            continue
        backends |= ctx.backends(fewer, more)
        if m1.separation_samples > m0.separation_samples:
            worse.append(f"{ctx.run_name(more)} has {m1.separation_samples} geometric-separation samples vs "
                         f"{m0.separation_samples} in {ctx.run_name(fewer)}")
            evidence[f"{fewer}_separation_samples"] = m0.separation_samples
            evidence[f"{more}_separation_samples"] = m1.separation_samples
        if m1.penetration_proxy - m0.penetration_proxy > tol:
            worse.append(f"{ctx.run_name(more)} proxy {m1.penetration_proxy:.6f} m > {ctx.run_name(fewer)} "
                         f"{m0.penetration_proxy:.6f} m")
    measured = ("measured counterexamples with more substeps: " + "; ".join(worse)) if worse else \
        "no counterexample among the measured cases (one scene is still no guarantee)"
    return Outcome(credit(a.every_diagnostic_improves is False), "false: improvement is not guaranteed",
                   measured, evidence, backends)
