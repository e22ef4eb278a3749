"""L03 lab-report figures: contact trajectories, clearance, friction lanes and camera frames or schematics, as PNGs.

Every function writes into a caller-given output folder (never the repository) and returns the paths it wrote.
Figures are built on `matplotlib.figure.Figure` with the Agg canvas, so no pyplot global state leaks between calls
or threads. Each figure names its cases, backend and engine version in a footer: a PNG copied out of its report
must still say where its numbers came from.
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Mapping
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.patches import Rectangle

from rubric import CaseResult, ContactCase, FrictionCase, contact_metrics, lane_metrics
from rubric.metrics import tilt

DPI = 110
# Distinct, colour-blind-friendly case colours (Okabe-Ito); lanes use their own Surface colour instead.
CASE_COLORS = ("#0072B2", "#D55E00", "#009E73", "#CC79A7", "#E69F00", "#56B4E9", "#000000")
CAMERA_TITLE = "Genesis camera"
SCHEMATIC_TITLE = "SCHEMATIC drawn from measured positions \u2014 rendering SKIP, not a camera image"
# Seconds shown before / after first contact in the zoomed contact panels.
ZOOM_BEFORE_S, ZOOM_AFTER_S = 0.05, 0.30
COUNT_OFFSET = 0.07


# ---------------------------------------------------------------------------------------------- shared helpers


FOOTER_IN = 0.3


def _new_figure(width: float, height: float) -> Figure:
    fig = Figure(figsize=(width, height), dpi=DPI, layout="constrained")
    FigureCanvasAgg(fig)
    # Reserve a strip at the bottom for the provenance footer; constrained layout ignores free-floating text.
    strip = FOOTER_IN / height
    fig.get_layout_engine().set(rect=(0.0, strip, 1.0, 1.0 - strip))
    return fig


def _safe_name(name: str) -> str:
    """A file-name fragment: spec names are already restricted, but a figure must never escape its folder."""
    return re.sub(r"[^A-Za-z0-9_.\-]", "_", name).strip(".") or "case"


def provenance_line(results: Iterable[CaseResult]) -> str:
    """'cases: N1, N2 | backend: cpu | genesis 1.3.3 | execution: warm', the footer every figure carries."""
    results = list(results)
    backends = sorted({r.backend for r in results})
    versions = sorted({r.provenance.versions.get("genesis", "?") for r in results if r.provenance})
    modes = sorted({r.provenance.execution_mode for r in results if r.provenance})
    parts = [
        "cases: " + ", ".join(r.spec.name for r in results),
        "backend: " + (", ".join(backends) or "n/a"),
        "genesis " + (", ".join(versions) or "version unknown"),
    ]
    if modes:
        parts.append("execution: " + ", ".join(modes))
    return "  |  ".join(parts)


def _finish(fig: Figure, results: list[CaseResult], path: Path, *, source: str, skipped: list[str] = (),
            notes: list[str] = ()) -> Path:
    footer = provenance_line(results)
    if skipped:
        footer += "  |  not drawn (no valid result): " + ", ".join(skipped)
    fig.text(0.5, 0.08 * FOOTER_IN / fig.get_figheight(), footer, ha="center", va="bottom", fontsize=8.5, color="#333333")
    # The PNG's own metadata records what it is and what it claims, so a reader (or a test) can tell a camera image
    # from a schematic, and a stop from a "not stopped", without parsing pixels.
    title = fig.get_suptitle() or path.stem
    metadata = {"Title": title, "Source": source, "Description": "\n".join([footer, *notes])}
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=DPI, metadata=metadata, pad_inches=0.15)
    return path


def _split_ok(results: Iterable[CaseResult]) -> tuple[list[CaseResult], list[str]]:
    results = list(results)
    return [r for r in results if r.ok and r.arrays], [r.spec.name for r in results if not (r.ok and r.arrays)]


def _case_label(spec: ContactCase) -> str:
    return f"{spec.name}: dt={spec.dt:g} s, substeps={spec.substeps} (substep_dt={spec.substep_dt:.4g} s)"


# ------------------------------------------------------------------------------------------------ contact figures


def contact_figures(results: Iterable[CaseResult] | Mapping[str, CaseResult], out_dir: str | Path) -> list[Path]:
    """Trajectory (z, vz, contacts) and clearance figures for the contact cases among `results`."""
    if isinstance(results, Mapping):
        results = results.values()
    contact = [r for r in results if isinstance(r.spec, ContactCase)]
    if not contact:
        return []
    out_dir = Path(out_dir)
    return [
        contact_trajectory_figure(contact, out_dir / "contact_trajectories.png"),
        clearance_figure(contact, out_dir / "contact_clearance.png"),
    ]


def contact_trajectory_figure(results: list[CaseResult], path: Path) -> Path:
    """Three stacked panels sharing time (z, vz, contact count): full window left, zoom on first contact right."""
    ok, skipped = _split_ok(results)
    fig = _new_figure(14, 9.5)
    axes = fig.subplots(3, 2, sharex="col", gridspec_kw={"width_ratios": (1.25, 1)})
    first = _earliest_first_contact(ok)
    for i, r in enumerate(ok):
        # Counts are small integers shared by all cases; a small offset keeps coincident steps distinguishable.
        _plot_contact_case(axes, r, CASE_COLORS[i % len(CASE_COLORS)], count_offset=COUNT_OFFSET * i)
    if ok:
        rest = ok[0].spec.expected_center_z
        axes[0, 0].axhline(rest, color="k", ls="--", lw=1, label=f"ideal rest height {rest:.3f} m")
        axes[0, 1].axhline(0.0, color="k", ls="--", lw=1, label="ideal rest height")
    _label_contact_axes(axes, first)
    axes[0, 0].legend(fontsize=8, loc="upper right")
    axes[0, 1].legend(fontsize=8, loc="lower right")
    fig.suptitle("L03 Part A: falling cube on a fixed table \u2014 height, vertical velocity and contacts", fontsize=13)
    return _finish(fig, results, path, source="measured trajectories", skipped=skipped)


def _earliest_first_contact(results: list[CaseResult]) -> float | None:
    times = [contact_metrics(r.spec, r.arrays).first_contact_time for r in results]
    times = [t for t in times if t is not None]
    return min(times) if times else None


def _plot_contact_case(axes, r: CaseResult, color: str, *, count_offset: float) -> None:
    spec, a = r.spec, r.arrays
    t = a["t"]
    label = _case_label(spec)
    height_mm = (a["z"] - spec.expected_center_z) * 1e3
    # Coarse cases get bigger markers so that their sample cadence (dt) is visible in the zoom.
    marker = dict(marker="o", ms=2.5 + 150 * spec.dt, mfc="none")
    axes[0, 0].plot(t, a["z"], color=color, lw=1.4, label=label)
    axes[0, 1].plot(t, height_mm, color=color, lw=1, **marker, label=spec.name)
    for col in (0, 1):
        axes[1, col].plot(t, a["vz"], color=color, lw=1.2 if col == 0 else 1, **({} if col == 0 else marker))
        axes[2, col].step(t, a["contact_count"] + count_offset, where="post", color=color, lw=1.4)


def _label_contact_axes(axes, first: float | None) -> None:
    axes[0, 0].set_ylabel("cube centre height z (m)")
    axes[0, 1].set_ylabel("z \u2212 ideal rest height (mm)")
    for col in (0, 1):
        axes[1, col].set_ylabel("vertical velocity vz (m/s)")
        axes[1, col].axhline(0.0, color="#888888", lw=0.8)
        axes[2, col].set_ylabel(f"contact count (cube\u2013table)\ncurves offset +{COUNT_OFFSET:g} per case")
        axes[2, col].set_xlabel("simulated time t (s)")
        axes[2, col].yaxis.get_major_locator().set_params(integer=True)
        for ax in axes[:, col]:
            ax.grid(alpha=0.3)
    axes[0, 0].set_title("full measured window")
    if first is None:
        axes[0, 1].set_title("zoom: no contact was reported in any case")
        return
    lo, hi = first - ZOOM_BEFORE_S, first + ZOOM_AFTER_S
    axes[0, 1].set_xlim(lo, hi)
    axes[0, 1].set_title(f"zoom around first contact (t \u2248 {first:.2f} s), markers = outer samples")
    _zoom_ylim(axes[0, 1], lo, hi)
    _zoom_ylim(axes[1, 1], lo, hi)


def _zoom_ylim(ax, lo: float, hi: float) -> None:
    """Fit the y range to what is visible in the zoomed x window (matplotlib autoscales over all data)."""
    values = []
    for line in ax.get_lines():
        x, y = np.asarray(line.get_xdata(), float), np.asarray(line.get_ydata(), float)
        if x.size > 1:
            values.append(y[(x >= lo) & (x <= hi)])
    values = np.concatenate(values) if values else np.array([])
    if values.size:
        vmin, vmax = float(values.min()), float(values.max())
        pad = 0.08 * max(vmax - vmin, 1e-6)
        ax.set_ylim(vmin - pad, vmax + pad)


def clearance_figure(results: list[CaseResult], path: Path) -> Path:
    """Bottom clearance with the declared tolerance; separation samples (no contact, clearance > tol) marked."""
    ok, skipped = _split_ok(results)
    fig = _new_figure(14, 8)
    full, zoom = fig.subplots(2, 1)
    first = _earliest_first_contact(ok)
    for i, r in enumerate(ok):
        _plot_clearance_case(full, zoom, r, CASE_COLORS[i % len(CASE_COLORS)])
    if ok:
        tol_mm = ok[0].spec.separation_tolerance * 1e3
        for ax in (full, zoom):
            ax.axhline(0.0, color="k", lw=1, label="table top (clearance 0)")
            ax.axhspan(0.0, tol_mm, color="#999999", alpha=0.25, label=f"separation tolerance {tol_mm:g} mm")
    full.set_title("bottom clearance = cube centre z \u2212 cube size/2 \u2212 table top z, full measured window")
    full.set_ylabel("clearance (mm)")
    full.legend(fontsize=8, loc="upper right")
    _clearance_zoom_axes(zoom, ok, first)
    for ax in (full, zoom):
        ax.set_xlabel("simulated time t (s)")
        ax.grid(alpha=0.3)
    fig.suptitle("L03 Part A: bottom clearance and observed geometric separation", fontsize=13)
    return _finish(fig, results, path, source="measured trajectories", skipped=skipped)


def separation_mask(spec: ContactCase, arrays: Mapping[str, np.ndarray]) -> np.ndarray:
    """Samples that count as geometric separation: after first contact, no contact and clearance > tolerance."""
    in_contact = arrays["contact_count"] > 0
    after = np.cumsum(in_contact) > 0
    return after & ~in_contact & (arrays["clearance"] > spec.separation_tolerance)


def _plot_clearance_case(full, zoom, r: CaseResult, color: str) -> None:
    spec, a = r.spec, r.arrays
    t, c_mm = a["t"], a["clearance"] * 1e3
    sep = separation_mask(spec, a)
    m = contact_metrics(spec, a)
    label = (f"{spec.name} (dt={spec.dt:g} s, substeps={spec.substeps}): min clearance {m.min_clearance * 1e3:+.2f} mm, "
             f"{int(sep.sum())} separation samples ({m.separation_duration:.2f} s)")
    full.plot(t, c_mm, color=color, lw=1.4, label=label)
    zoom.plot(t, c_mm, color=color, lw=1, marker="o", ms=2)
    zoom.plot(t[sep], c_mm[sep], ls="none", marker="X", ms=10, color=color, mec="k", mew=0.7)


def _clearance_zoom_axes(zoom, ok: list[CaseResult], first: float | None) -> None:
    zoom.set_ylabel("clearance (mm), zoomed")
    if first is None or not ok:
        zoom.set_title("zoom: no contact was reported in any case")
        return
    end = max(float(r.arrays["t"][-1]) for r in ok)
    zoom.set_xlim(first - ZOOM_BEFORE_S, end)
    # Down to the deepest sample (it may precede a case's first reported contact), up to the highest sample after
    # each case's own first contact: the fall itself would flatten the millimetre scale.
    deepest = min(float(r.arrays["clearance"].min()) for r in ok) * 1e3
    after = np.concatenate([_after_first_contact(r.arrays, "clearance") for r in ok]) * 1e3
    tol_mm = ok[0].spec.separation_tolerance * 1e3
    low, high = min(deepest, 0.0), max(float(after.max()), 2.5 * tol_mm)
    pad = 0.08 * (high - low)
    zoom.set_ylim(low - pad, high + pad)
    zoom.set_title("after first contact: markers = outer samples; \u2716 = geometric separation sample "
                   "(contact count 0 and clearance > tolerance)")
    zoom.plot([], [], ls="none", marker="X", ms=10, color="#BBBBBB", mec="k", label="geometric separation sample")
    zoom.legend(fontsize=8.5, loc="lower right")


def _after_first_contact(arrays: Mapping[str, np.ndarray], key: str) -> np.ndarray:
    in_contact = arrays["contact_count"] > 0
    return arrays[key][np.cumsum(in_contact) > 0]


# ----------------------------------------------------------------------------------------------- friction figures


def _lane_color(lane) -> tuple[float, float, float]:
    return tuple(lane.color)


def _lane_label(spec: FrictionCase, lane) -> str:
    m_pair = max(spec.table.friction, lane.friction)
    return f"{lane.name}: cube \u03bc={lane.friction:.2f}, table \u03bc={spec.table.friction:.2f} \u2192 pair \u03bc={m_pair:.2f}"


def friction_figure(result: CaseResult, out_dir: str | Path) -> Path:
    """x(t), vx(t) with the stop-speed band and |omega|(t) per lane, with each lane's sustained stop marked."""
    spec: FrictionCase = result.spec
    path = Path(out_dir) / f"friction_{_safe_name(spec.name)}.png"
    fig = _new_figure(12, 10)
    axes = fig.subplots(3, 1, sharex=True)
    if result.ok and result.arrays:
        for k, lane in enumerate(spec.lanes):
            _plot_lane(axes, result, lane, k)
        axes[1].axhspan(-spec.stop_speed, spec.stop_speed, color="#777777", alpha=0.3,
                        label=f"stop band |vx| < {spec.stop_speed:g} m/s (hold {spec.hold:g} s)")
    _label_friction_axes(axes)
    fig.suptitle(f"L03 Part B: sliding cubes, run '{spec.name}' (table \u03bc={spec.table.friction:.2f}, "
                 f"dt={spec.dt:g} s, substeps={spec.substeps})", fontsize=13)
    ok, skipped = _split_ok([result])
    notes = [stop_note(spec, result.arrays, lane.name) for lane in spec.lanes] if ok else []
    return _finish(fig, [result], path, source="measured trajectories", skipped=skipped, notes=notes)


def stop_note(spec: FrictionCase, arrays: Mapping[str, np.ndarray], lane_name: str) -> str:
    """'low: stopped at t=0.45 s after 0.410 m' or 'low: NOT STOPPED within the measured window (...)'."""
    stop = lane_metrics(spec, arrays, lane_name).stop
    if stop.stopped:
        return f"{lane_name}: stopped at t={stop.time:.2f} s after {stop.distance:.3f} m"
    t, x = arrays["t"], arrays[f"{lane_name}_x"]
    return (f"{lane_name}: NOT STOPPED within the measured window (0\u2013{t[-1]:.2f} s; "
            f"final displacement {x[-1] - x[0]:.3f} m)")


def _plot_lane(axes, result: CaseResult, lane, k: int) -> None:
    spec, a = result.spec, result.arrays
    t = a["t"]
    color = _lane_color(lane)
    disp = a[f"{lane.name}_x"] - a[f"{lane.name}_x"][0]
    omega = np.linalg.norm(a[f"{lane.name}_omega"], axis=1)
    series = (disp, a[f"{lane.name}_vx"], omega)
    for ax, y in zip(axes, series):
        ax.plot(t, y, color=color, lw=2, label=_lane_label(spec, lane))
    stop = lane_metrics(spec, a, lane.name).stop
    if stop.stopped:
        i = stop.index
        for ax, y in zip(axes, series):
            ax.axvline(stop.time, color=color, ls="--", lw=1.2)
            ax.plot([t[i]], [y[i]], "o", ms=9, color=color, mec="k", zorder=5)
        axes[0].annotate(f"{lane.name} stops: t={stop.time:.2f} s, distance={stop.distance:.3f} m",
                         (t[i], disp[i]), xytext=(12, -18 - 16 * k), textcoords="offset points",
                         fontsize=9, color="k", arrowprops=dict(arrowstyle="-", color=color))
    else:
        axes[0].text(0.99, 0.05 + 0.09 * k, stop_note(spec, a, lane.name), transform=axes[0].transAxes,
                     ha="right", fontsize=9, color="k", bbox=dict(fc="white", ec=color, lw=1.5))


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
    path = Path(out_dir) / f"friction_compare_{_safe_name(baseline.spec.name)}_vs_{_safe_name(modified.spec.name)}.png"
    runs, skipped = _split_ok([baseline, modified])
    lanes = baseline.spec.lanes
    fig = _new_figure(6.5 * len(lanes), 8.5)
    axes = fig.subplots(2, len(lanes), sharex=True, squeeze=False)
    # Baseline as a wide pale band, the modified run as a dashed line on top: identical curves stay both visible.
    styles = (dict(ls="-", lw=5, alpha=0.35), dict(ls=(0, (4, 2)), lw=1.8, alpha=1.0))
    for col, lane in enumerate(lanes):
        for run, style in zip(runs, styles):
            _plot_compared_lane(axes[:, col], run, lane.name, style)
        _label_compared_lane(axes[:, col], runs, lane)
    fig.suptitle(f"L03 Part B: one-factor comparison '{baseline.spec.name}' (wide pale) vs "
                 f"'{modified.spec.name}' (dashed): only table friction changes", fontsize=13)
    return _finish(fig, [baseline, modified], path, source="measured trajectories", skipped=skipped)


def _plot_compared_lane(axes, run: CaseResult, lane_name: str, style: dict) -> None:
    spec, a = run.spec, run.arrays
    lane = next(item for item in spec.lanes if item.name == lane_name)
    t, x, vx = a["t"], a[f"{lane_name}_x"], a[f"{lane_name}_vx"]
    disp = x - x[0]
    stop = lane_metrics(spec, a, lane_name).stop
    where = f"stop {stop.distance:.3f} m at {stop.time:.2f} s" if stop.stopped else "not stopped in window"
    pair = max(spec.table.friction, lane.friction)
    label = f"{spec.name}: table \u03bc={spec.table.friction:.2f}, pair \u03bc={pair:.2f}; {where}"
    color = _lane_color(lane)
    axes[0].plot(t, disp, color=color, label=label, **style)
    axes[1].plot(t, vx, color=color, **style)
    if stop.stopped:
        axes[0].plot([stop.time], [disp[stop.index]], "o", ms=9, color=color, mec="k", zorder=5)
        axes[1].plot([stop.time], [vx[stop.index]], "o", ms=9, color=color, mec="k", zorder=5)


def _stop_change(runs: list[CaseResult], lane_name: str) -> str:
    """'stop distance 0.410 -> 0.675 m (+0.265 m)', or which run did not stop: the comparison's one-line answer."""
    stops = [lane_metrics(r.spec, r.arrays, lane_name).stop for r in runs]
    if len(stops) != 2:
        return "comparison needs both runs"
    if not all(s.stopped for s in stops):
        missing = [r.spec.name for r, s in zip(runs, stops) if not s.stopped]
        return "not stopped within the measured window: " + ", ".join(missing)
    a, b = stops[0].distance, stops[1].distance
    return f"stop distance {a:.3f} \u2192 {b:.3f} m ({b - a:+.3f} m)"


def _label_compared_lane(axes, runs: list[CaseResult], lane) -> None:
    pairs = " \u2192 ".join(f"{max(r.spec.table.friction, lane.friction):.2f}" for r in runs)
    axes[0].set_title(f"lane '{lane.name}' (cube \u03bc={lane.friction:.2f}): pair \u03bc {pairs}\n"
                      f"{_stop_change(runs, lane.name)}", fontsize=11)
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


# ---------------------------------------------------------------------------------- camera frames or schematics


def has_frames(result: CaseResult) -> bool:
    """True when the run rendered: both camera frames are non-empty RGB images."""
    frames = [result.arrays.get(name) for name in ("frame_initial", "frame_final")]
    return all(f is not None and f.ndim == 3 and f.size > 0 for f in frames)


def frames_figure(result: CaseResult, out_dir: str | Path) -> Path:
    """Initial and final Genesis camera frames side by side, or a clearly labelled schematic when rendering was off."""
    name = _safe_name(result.spec.name)
    if has_frames(result):
        return _camera_figure(result, Path(out_dir) / f"frames_{name}_camera.png")
    return _schematic_figure(result, Path(out_dir) / f"frames_{name}_schematic.png")


def _camera_figure(result: CaseResult, path: Path) -> Path:
    a = result.arrays
    fig = _new_figure(12, 5.2)
    axes = fig.subplots(1, 2)
    t_end = float(a["t"][-1]) if "t" in a and len(a["t"]) else float("nan")
    for ax, key, when in zip(axes, ("frame_initial", "frame_final"), ("initial frame", f"final frame, t={t_end:.2f} s")):
        ax.imshow(a[key])
        ax.set_title(f"{when} ({a[key].shape[1]}\u00d7{a[key].shape[0]} px)")
        ax.set_axis_off()
    fig.suptitle(f"{CAMERA_TITLE}: case '{result.spec.name}'", fontsize=13)
    return _finish(fig, [result], path, source="camera")


def _schematic_figure(result: CaseResult, path: Path) -> Path:
    fig = _new_figure(13, 5.0)
    if not (result.ok and result.arrays):
        ax = fig.subplots()
        ax.text(0.5, 0.5, f"no measured positions: case status '{result.status}'", ha="center", transform=ax.transAxes)
        ax.set_axis_off()
    elif isinstance(result.spec, ContactCase):
        _contact_schematic(fig, result)
    else:
        _friction_schematic(fig, result)
    fig.suptitle(f"{SCHEMATIC_TITLE}\ncase '{result.spec.name}'", fontsize=12, color="#8B0000")
    return _finish(fig, [result], path, source="schematic")


def _contact_schematic(fig: Figure, result: CaseResult) -> None:
    """Side view (x-z) of the table and the cube at its start pose and its final measured height."""
    spec: ContactCase = result.spec
    a = result.arrays
    side, zoom = fig.subplots(1, 2, gridspec_kw={"width_ratios": (1.5, 1)})
    table, cube = spec.table, spec.cube
    final_z, final_tilt = float(a["z"][-1]), float(np.degrees(tilt(a["quat"][-1:])[0]))
    for ax in (side, zoom):
        ax.add_patch(Rectangle((table.pos[0] - table.size[0] / 2, table.pos[2] - table.size[2] / 2),
                               table.size[0], table.size[2], fc="#C8B89A", ec="k", label="table (fixed)"))
        _cube_square(ax, cube.pos[0], cube.pos[2], cube.size, 0.0, fc="none", ec="#555555", ls="--",
                     label=f"start pose, z={cube.pos[2]:.3f} m (t=0, declared)")
        _cube_square(ax, cube.pos[0], final_z, cube.size, final_tilt, fc=tuple(cube.color), ec="k", alpha=0.85,
                     label=f"final, z={final_z:.4f} m (t={a['t'][-1]:.2f} s, measured)")
        ax.axhline(spec.expected_center_z, color="k", ls=":", lw=1, label="ideal rest centre height")
        ax.set_aspect("equal")
        ax.set_xlabel("x (m)")
        ax.set_ylabel("z (m)")
    side.set_xlim(table.pos[0] - table.size[0] / 2 - 0.05, table.pos[0] + table.size[0] / 2 + 0.05)
    side.set_ylim(table.pos[2] - table.size[2], cube.pos[2] + cube.size)
    side.set_title("side view (x\u2013z), true scale")
    side.legend(fontsize=8, loc="upper right")
    # The deepest sample is where the penetration proxy comes from; at true scale only the zoom can show it.
    low = int(np.argmin(a["z"]))
    _cube_square(zoom, cube.pos[0], float(a["z"][low]), cube.size, 0.0, fc="none", ec="#B00000", ls="--", lw=1.5)
    _contact_schematic_zoom(zoom, spec, a, low)


def _contact_schematic_zoom(ax, spec: ContactCase, a: Mapping[str, np.ndarray], low: int) -> None:
    m = contact_metrics(spec, a)
    top = spec.table.top_z
    ax.set_xlim(spec.cube.pos[0] - 1.2 * spec.cube.size, spec.cube.pos[0] + 2.8 * spec.cube.size)
    ax.set_ylim(top - 0.6 * spec.cube.size, top + 1.6 * spec.cube.size)
    ax.set_title("zoom on the contact (x\u2013z)")
    notes = (
        f"red dashed: deepest sample\n  z={a['z'][low]:.4f} m at t={a['t'][low]:.2f} s\n"
        f"penetration proxy {m.penetration_proxy * 1e3:.2f} mm\n"
        f"final clearance {m.final_clearance * 1e3:+.2f} mm\n"
        f"final tilt {np.degrees(tilt(a['quat'][-1:])[0]):.2f}\u00b0\n\n"
        "x is the declared start x:\ncontact runs record z only"
    )
    ax.text(0.98, 0.97, notes, transform=ax.transAxes, va="top", ha="right", fontsize=8.5,
            bbox=dict(fc="white", ec="#999999"))


def _cube_square(ax, x: float, z: float, size: float, angle_deg: float, **style) -> None:
    ax.add_patch(Rectangle((x - size / 2, z - size / 2), size, size, angle=angle_deg, rotation_point="center", **style))


def _friction_schematic(fig: Figure, result: CaseResult) -> None:
    """Top view (x-y) of the table and each lane's start and sustained-stop (or final) position."""
    spec: FrictionCase = result.spec
    a = result.arrays
    ax = fig.subplots()
    tx, ty, _ = spec.table.pos
    sx, sy, _ = spec.table.size
    ax.add_patch(Rectangle((tx - sx / 2, ty - sy / 2), sx, sy, fc="#E8DFC8", ec="k", label="table (top view)"))
    s = spec.cube_size
    for lane in spec.lanes:
        _lane_schematic(ax, spec, a, lane, s)
    ax.add_patch(Rectangle((0, 0), 0, 0, fc="none", ec="#555555", ls="--", label="dashed outline: position at t=0"))
    ax.set_aspect("equal")
    ax.set_xlim(tx - sx / 2 - 0.05, tx + sx / 2 + 0.05)
    ax.set_ylim(ty - sy / 2 - 0.05, ty + sy / 2 + 0.05)
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_title(f"top view (x\u2013y): start at measurement time zero \u2192 sustained stop, "
                 f"table \u03bc={spec.table.friction:.2f}")
    ax.legend(fontsize=8, loc="upper right")


def _lane_schematic(ax, spec: FrictionCase, a: Mapping[str, np.ndarray], lane, s: float) -> None:
    x, y = a[f"{lane.name}_x"], a[f"{lane.name}_y"]
    stop = lane_metrics(spec, a, lane.name).stop
    end = stop.index if stop.stopped else len(x) - 1
    what = (f"stop after {stop.distance:.3f} m at t={stop.time:.2f} s" if stop.stopped
            else f"NOT STOPPED within the window; at t={a['t'][-1]:.2f} s")
    color = _lane_color(lane)
    ax.add_patch(Rectangle((x[0] - s / 2, y[0] - s / 2), s, s, fc="none", ec=color, ls="--", lw=1.5))
    ax.add_patch(Rectangle((x[end] - s / 2, y[end] - s / 2), s, s, fc=color, ec="k",
                           label=f"{lane.name} (cube \u03bc={lane.friction:.2f}): {what}"))
    ax.annotate("", (x[end] - s / 2, y[end]), (x[0] + s / 2, y[0]), arrowprops=dict(arrowstyle="->", color=color))
    ax.plot(x[: end + 1], y[: end + 1], color=color, lw=0.8, alpha=0.6)


# ------------------------------------------------------------------------------------------------- all at once


def lab_figures(results: Mapping[str, CaseResult], out_dir: str | Path, *,
                baseline: str = "friction-baseline", modified: str = "friction-table-0.30") -> list[Path]:
    """Every L03 figure the results support: contact, per friction run, the one-factor comparison, frames."""
    out_dir = Path(out_dir)
    paths = contact_figures(results, out_dir)
    friction = [r for r in results.values() if isinstance(r.spec, FrictionCase)]
    paths += [friction_figure(r, out_dir) for r in friction]
    if baseline in results and modified in results:
        paths.append(friction_comparison_figure(results[baseline], results[modified], out_dir))
    paths += [frames_figure(r, out_dir) for r in results.values()]
    return paths


__all__ = [
    "CAMERA_TITLE",
    "SCHEMATIC_TITLE",
    "clearance_figure",
    "contact_figures",
    "contact_trajectory_figure",
    "frames_figure",
    "friction_comparison_figure",
    "friction_figure",
    "has_frames",
    "lab_figures",
    "provenance_line",
    "separation_mask",
    "stop_note",
]
