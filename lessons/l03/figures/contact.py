"""Part A figures: height, vertical velocity and contact count of the falling cube; bottom clearance."""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from pathlib import Path

import numpy as np

from rubric import CaseResult, ContactCase
from rubric.metrics import separation_mask

from .common import CASE_COLORS, COUNT_OFFSET, ZOOM_AFTER_S, ZOOM_BEFORE_S, case_label, finish, metrics_of, new_figure, split_ok


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
    ok, skipped = split_ok(results)
    fig = new_figure(14, 9.5)
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
    return finish(fig, results, path, source="measured trajectories", skipped=skipped)


def _earliest_first_contact(results: list[CaseResult]) -> float | None:
    times = [metrics_of(r).first_contact_time for r in results]
    times = [t for t in times if t is not None]
    return min(times) if times else None


def _plot_contact_case(axes, r: CaseResult, color: str, *, count_offset: float) -> None:
    spec, a = r.spec, r.arrays
    t = a["t"]
    label = case_label(spec)
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
    ok, skipped = split_ok(results)
    fig = new_figure(14, 8)
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
    return finish(fig, results, path, source="measured trajectories", skipped=skipped)


def _plot_clearance_case(full, zoom, r: CaseResult, color: str) -> None:
    spec, a = r.spec, r.arrays
    t, c_mm = a["t"], a["clearance"] * 1e3
    sep = separation_mask(spec, a)
    m = metrics_of(r)
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
    after = np.concatenate([_after_first_contact(r, "clearance") for r in ok]) * 1e3
    tol_mm = ok[0].spec.separation_tolerance * 1e3
    low, high = min(deepest, 0.0), max(float(after.max()), 2.5 * tol_mm)
    pad = 0.08 * (high - low)
    zoom.set_ylim(low - pad, high + pad)
    zoom.set_title("after first contact: markers = outer samples; \u2716 = geometric separation sample "
                   "(contact count 0 and clearance > tolerance)")
    zoom.plot([], [], ls="none", marker="X", ms=10, color="#BBBBBB", mec="k", label="geometric separation sample")
    zoom.legend(fontsize=8.5, loc="lower right")


def _after_first_contact(result: CaseResult, key: str) -> np.ndarray:
    first = metrics_of(result).first_contact_index
    return result.arrays[key][first:] if first is not None else result.arrays[key][:0]
