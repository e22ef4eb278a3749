"""Part B figures: each friction run's lanes (x, vx, |omega|, sustained stop) and the one-factor comparison.

Stops and pair frictions come from the run's stored metrics: the pair value is the one the engine assigned to the
lane's contacts, so a figure can never show a recomputed rule that disagrees with what was simulated.
"""

from __future__ import annotations

import textwrap
from pathlib import Path

import numpy as np

from rubric import CaseResult, FrictionCase, field_changes
from rubric.metrics import TUMBLE_EXPLANATION, LaneMetrics, tilt, tumble_angle_deg
from rubric.relations import stop_change

from .common import finish, lane_color, metrics_of, new_figure, safe_name, split_ok


def pair_text(m: LaneMetrics) -> str:
    """The pair friction the engine assigned to the lane's contacts (stored metrics), never a recomputed rule."""
    if m.pair_friction is None:
        return "pair \u03bc: no contact reported"
    flag = "" if m.pair_friction_agrees else f" \u2260 rule {m.pair_friction_rule:.2f}!"
    return f"pair \u03bc={m.pair_friction:.2f} (engine){flag}"


def tumble_text(m: LaneMetrics) -> str:
    """'max tilt 12.3°', 'TUMBLED (max tilt 90.0°)' past the tip-over angle, or '' where tilt was not recorded."""
    if m.max_tilt_deg is None:
        return ""
    return f"TUMBLED (max tilt {m.max_tilt_deg:.1f}\u00b0)" if m.tumbled else f"max tilt {m.max_tilt_deg:.1f}\u00b0"


def _lane_label(m: LaneMetrics) -> str:
    tilt = tumble_text(m)
    return (f"{m.lane}: cube \u03bc={m.cube_friction:.2f}, table \u03bc={m.table_friction:.2f} \u2192 {pair_text(m)}"
            + (f"; {tilt}" if tilt else ""))


def friction_figure(result: CaseResult, out_dir: str | Path) -> Path:
    """x(t), vx(t) with the stop-speed band and |omega|(t) per lane, with each lane's sustained stop marked."""
    spec: FrictionCase = result.spec
    path = Path(out_dir) / f"friction_{safe_name(spec.name)}.png"
    fig = new_figure(12, 10)
    axes = fig.subplots(3, 1, sharex=True)
    if result.ok and result.arrays:
        for k, lane in enumerate(spec.lanes):
            _plot_lane(axes, result, lane, k)
        axes[1].axhspan(-spec.stop_speed, spec.stop_speed, color="#777777", alpha=0.3,
                        label=f"stop band |vx| < {spec.stop_speed:g} m/s (hold {spec.hold:g} s)")
        _tumble_box(axes[2], result)
    _label_friction_axes(axes)
    fig.suptitle(f"L03 Part B: sliding cubes, run '{spec.name}' (table \u03bc={spec.table.friction:.2f}, "
                 f"dt={spec.dt:g} s, substeps={spec.substeps})", fontsize=13)
    ok, skipped = split_ok([result])
    notes = [stop_note(result, lane.name) for lane in spec.lanes] if ok else []
    return finish(fig, [result], path, source="measured trajectories", skipped=skipped, notes=notes)


def _tip_over_index(result: CaseResult, m: LaneMetrics) -> int | None:
    """First sample whose tilt is past the tip-over angle: where a tumbled cube went over its edge."""
    quat = result.arrays.get(f"{m.lane}_quat")
    if not m.tumbled or quat is None:
        return None
    cube = result.spec.cube_size
    return int(np.flatnonzero(np.degrees(tilt(quat)) > tumble_angle_deg(cube, cube))[0])


def _mark_tumble(axes, result: CaseResult, m: LaneMetrics, color, series) -> None:
    """An 'X' where a tumbled lane's cube tipped over its edge, on every panel (the box of words is _tumble_box)."""
    i = _tip_over_index(result, m)
    if i is None:
        return
    t = result.arrays["t"]
    for ax, y in zip(axes, series):
        ax.plot([t[i]], [y[i]], "X", ms=12, color=color, mec="k", zorder=6)


def _tumble_box(ax, result: CaseResult) -> None:
    """One boxed note naming every tumbled lane in words (not colour alone), and why its stop is not a sliding stop."""
    lanes = [metrics_of(result).lane(lane.name) for lane in result.spec.lanes]
    tumbled = [m for m in lanes if m.tumbled]
    if not tumbled:
        return
    t = result.arrays["t"]
    lines = [f"{m.lane}: {tumble_text(m)}, tips over its edge at t={t[_tip_over_index(result, m)]:.2f} s (X)"
             for m in tumbled]
    text = "\n".join(lines + textwrap.wrap(TUMBLE_EXPLANATION, 70))
    ax.text(0.99, 0.95, text, transform=ax.transAxes, ha="right", va="top", fontsize=9.5, color="k",
            bbox=dict(fc="#fff4dc", ec="#7a4b00", lw=1.5))


def stop_note(result: CaseResult, lane_name: str) -> str:
    """'low: stopped at t=0.45 s after 0.410 m' or 'low: NOT STOPPED within the measured window (...)', followed by
    '; TUMBLED (max tilt ...)' when the cube tipped over onto another face."""
    m = metrics_of(result).lane(lane_name)
    tumble = f"; {tumble_text(m)}: not a sliding stop" if m.tumbled else ""
    if m.stop.stopped:
        return f"{lane_name}: stopped at t={m.stop.time:.2f} s after {m.stop.distance:.3f} m{tumble}"
    return (f"{lane_name}: NOT STOPPED within the measured window (0\u2013{result.arrays['t'][-1]:.2f} s; "
            f"final displacement {m.final_displacement:.3f} m){tumble}")


def _plot_lane(axes, result: CaseResult, lane, k: int) -> None:
    spec, a = result.spec, result.arrays
    t = a["t"]
    color = lane_color(lane)
    disp = a[f"{lane.name}_x"] - a[f"{lane.name}_x"][0]
    omega = np.linalg.norm(a[f"{lane.name}_omega"], axis=1)
    series = (disp, a[f"{lane.name}_vx"], omega)
    m = metrics_of(result).lane(lane.name)
    for ax, y in zip(axes, series):
        ax.plot(t, y, color=color, lw=2, label=_lane_label(m))
    stop = m.stop
    if stop.stopped:
        i = stop.index
        for ax, y in zip(axes, series):
            ax.axvline(stop.time, color=color, ls="--", lw=1.2)
            ax.plot([t[i]], [y[i]], "o", ms=9, color=color, mec="k", zorder=5)
        axes[0].annotate(f"{lane.name} stops: t={stop.time:.2f} s, distance={stop.distance:.3f} m",
                         (t[i], disp[i]), xytext=(12, -18 - 16 * k), textcoords="offset points",
                         fontsize=9, color="k", arrowprops=dict(arrowstyle="-", color=color))
    else:
        axes[0].text(0.99, 0.05 + 0.09 * k, stop_note(result, lane.name), transform=axes[0].transAxes,
                     ha="right", fontsize=9, color="k", bbox=dict(fc="white", ec=color, lw=1.5))
    _mark_tumble(axes, result, m, color, series)


def _label_friction_axes(axes) -> None:
    axes[0].set_ylabel("displacement x \u2212 x\u2080 (m)")
    axes[1].set_ylabel("velocity vx (m/s)")
    axes[2].set_ylabel("|angular velocity \u03c9| (rad/s)")
    axes[2].set_xlabel("time since measurement start t (s)")
    axes[0].set_title("dashed line + dot: first sample of a sustained stop (|vx| below the band for the hold interval)",
                      fontsize=9)
    for ax in axes:
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=9, loc="center right")
    axes[1].legend(fontsize=9, loc="upper right")


def friction_comparison_figure(baseline: CaseResult, modified: CaseResult, out_dir: str | Path) -> Path:
    """Per lane, the baseline and the modified run overlaid: displacement and velocity, stops marked."""
    path = Path(out_dir) / f"friction_compare_{safe_name(baseline.spec.name)}_vs_{safe_name(modified.spec.name)}.png"
    runs, skipped = split_ok([baseline, modified])
    lanes = baseline.spec.lanes
    fig = new_figure(6.5 * len(lanes), 8.5)
    axes = fig.subplots(2, len(lanes), sharex=True, squeeze=False)
    # Baseline as a wide pale band, the modified run as a dashed line on top: identical curves stay both visible.
    styles = (dict(ls="-", lw=5, alpha=0.35), dict(ls=(0, (4, 2)), lw=1.8, alpha=1.0))
    for col, lane in enumerate(lanes):
        for run, style in zip(runs, styles):
            _plot_compared_lane(axes[:, col], run, lane.name, style)
        _label_compared_lane(axes[:, col], runs, lane)
    changed = ", ".join(c.field + (" (visual)" if c.visual else "")
                        for c in field_changes(baseline.spec, modified.spec)) or "nothing"
    fig.suptitle(f"L03 Part B: '{baseline.spec.name}' (wide pale) vs '{modified.spec.name}' (dashed); "
                 f"changed: {changed}", fontsize=13)
    return finish(fig, [baseline, modified], path, source="measured trajectories", skipped=skipped)


def _plot_compared_lane(axes, run: CaseResult, lane_name: str, style: dict) -> None:
    spec, a = run.spec, run.arrays
    lane = next(item for item in spec.lanes if item.name == lane_name)
    t, x, vx = a["t"], a[f"{lane_name}_x"], a[f"{lane_name}_vx"]
    disp = x - x[0]
    m = metrics_of(run).lane(lane_name)
    stop = m.stop
    where = f"stop {stop.distance:.3f} m at {stop.time:.2f} s" if stop.stopped else "not stopped in window"
    if m.tumbled:
        where += "; TUMBLED"
    label = f"{spec.name}: table \u03bc={m.table_friction:.2f}, {pair_text(m)}; {where}"
    color = lane_color(lane)
    axes[0].plot(t, disp, color=color, label=label, **style)
    axes[1].plot(t, vx, color=color, **style)
    if stop.stopped:
        axes[0].plot([stop.time], [disp[stop.index]], "o", ms=9, color=color, mec="k", zorder=5)
        axes[1].plot([stop.time], [vx[stop.index]], "o", ms=9, color=color, mec="k", zorder=5)


def _stop_change(runs: list[CaseResult], lane_name: str) -> str:
    """'stop distance 0.410 -> 0.675 m (+0.265 m)', or which run did not stop: the comparison's one-line answer."""
    lanes = [metrics_of(r).lane(lane_name) for r in runs]
    if len(lanes) != 2:
        return "comparison needs both runs"
    change = stop_change(*lanes)
    if change is None:
        missing = [r.spec.name for r, m in zip(runs, lanes) if not m.stop.stopped]
        return "not stopped within the measured window: " + ", ".join(missing)
    return f"stop distance {lanes[0].stop.distance:.3f} \u2192 {lanes[1].stop.distance:.3f} m ({change:+.3f} m)"


def _label_compared_lane(axes, runs: list[CaseResult], lane) -> None:
    engine = [metrics_of(r).lane(lane.name).pair_friction for r in runs]
    pairs = " \u2192 ".join("no contact" if v is None else f"{v:.2f}" for v in engine) + " (engine)"
    tumbled = [r.spec.name for r in runs if metrics_of(r).lane(lane.name).tumbled]
    tumble = f"\nTUMBLED in {', '.join(tumbled)}: not a sliding stop" if tumbled else ""
    axes[0].set_title(f"lane '{lane.name}' (cube \u03bc={lane.friction:.2f}): pair \u03bc {pairs}\n"
                      f"{_stop_change(runs, lane.name)}{tumble}", fontsize=11)
    axes[0].set_ylabel("displacement x \u2212 x\u2080 (m)")
    axes[1].set_ylabel("velocity vx (m/s)")
    axes[1].set_xlabel("time since measurement start t (s)")
    if runs:
        stop_speed = runs[0].spec.stop_speed
        axes[1].axhspan(-stop_speed, stop_speed, color="#777777", alpha=0.3, label=f"|vx| < {stop_speed:g} m/s")
        axes[1].legend(fontsize=8, loc="upper right")
    axes[0].legend(fontsize=8, loc="lower right")
    for ax in axes:
        ax.grid(alpha=0.3)
