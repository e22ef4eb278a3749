"""Initial and final frames: the Genesis camera images when the run rendered, else schematics labelled as drawn
from measured positions (never passed off as camera images)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.figure import Figure
from matplotlib.patches import Rectangle

from rubric import CaseResult, ContactCase, FrictionCase
from rubric.metrics import tilt

from .common import CAMERA_TITLE, SCHEMATIC_TITLE, finish, lane_color, metrics_of, new_figure, safe_name


def has_frames(result: CaseResult) -> bool:
    """True when the run rendered: both camera frames are non-empty RGB images."""
    frames = [result.arrays.get(name) for name in ("frame_initial", "frame_final")]
    return all(f is not None and f.ndim == 3 and f.size > 0 for f in frames)


def frames_figure(result: CaseResult, out_dir: str | Path) -> Path:
    """Initial and final Genesis camera frames side by side, or a clearly labelled schematic when rendering was off."""
    name = safe_name(result.spec.name)
    if has_frames(result):
        return _camera_figure(result, Path(out_dir) / f"frames_{name}_camera.png")
    return _schematic_figure(result, Path(out_dir) / f"frames_{name}_schematic.png")


def _camera_figure(result: CaseResult, path: Path) -> Path:
    a = result.arrays
    fig = new_figure(12, 5.2)
    axes = fig.subplots(1, 2)
    t_end = float(a["t"][-1]) if "t" in a and len(a["t"]) else float("nan")
    for ax, key, when in zip(axes, ("frame_initial", "frame_final"), ("initial frame", f"final frame, t={t_end:.2f} s")):
        ax.imshow(a[key])
        ax.set_title(f"{when} ({a[key].shape[1]}\u00d7{a[key].shape[0]} px)")
        ax.set_axis_off()
    fig.suptitle(f"{CAMERA_TITLE}: case '{result.spec.name}'", fontsize=13)
    return finish(fig, [result], path, source="camera")


def _schematic_figure(result: CaseResult, path: Path) -> Path:
    fig = new_figure(13, 5.0)
    if not (result.ok and result.arrays):
        ax = fig.subplots()
        ax.text(0.5, 0.5, f"no measured positions: case status '{result.status}'", ha="center", transform=ax.transAxes)
        ax.set_axis_off()
    elif isinstance(result.spec, ContactCase):
        _contact_schematic(fig, result)
    else:
        _friction_schematic(fig, result)
    fig.suptitle(f"{SCHEMATIC_TITLE}\ncase '{result.spec.name}'", fontsize=12, color="#8B0000")
    return finish(fig, [result], path, source="schematic")


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
    _contact_schematic_zoom(zoom, result, low)


def _contact_schematic_zoom(ax, result: CaseResult, low: int) -> None:
    spec, a = result.spec, result.arrays
    m = metrics_of(result)
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
        _lane_schematic(ax, result, lane, s)
    ax.add_patch(Rectangle((0, 0), 0, 0, fc="none", ec="#555555", ls="--", label="dashed outline: position at t=0"))
    ax.set_aspect("equal")
    ax.set_xlim(tx - sx / 2 - 0.05, tx + sx / 2 + 0.05)
    ax.set_ylim(ty - sy / 2 - 0.05, ty + sy / 2 + 0.05)
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_title(f"top view (x\u2013y): start at measurement time zero \u2192 sustained stop, "
                 f"table \u03bc={spec.table.friction:.2f}")
    ax.legend(fontsize=8, loc="upper right")


def _lane_schematic(ax, result: CaseResult, lane, s: float) -> None:
    a = result.arrays
    x, y = a[f"{lane.name}_x"], a[f"{lane.name}_y"]
    stop = metrics_of(result).lane(lane.name).stop
    end = stop.index if stop.stopped else len(x) - 1
    what = (f"stop after {stop.distance:.3f} m at t={stop.time:.2f} s" if stop.stopped
            else f"NOT STOPPED within the window; at t={a['t'][-1]:.2f} s")
    color = lane_color(lane)
    ax.add_patch(Rectangle((x[0] - s / 2, y[0] - s / 2), s, s, fc="none", ec=color, ls="--", lw=1.5))
    ax.add_patch(Rectangle((x[end] - s / 2, y[end] - s / 2), s, s, fc=color, ec="k",
                           label=f"{lane.name} (cube \u03bc={lane.friction:.2f}): {what}"))
    ax.annotate("", (x[end] - s / 2, y[end]), (x[0] + s / 2, y[0]), arrowprops=dict(arrowstyle="->", color=color))
    ax.plot(x[: end + 1], y[: end + 1], color=color, lw=0.8, alpha=0.6)
