"""Discrepancy-audit figures: two measurements of one case spec overlaid, their difference below, classification on top.

Each side is told apart by line style, marker and legend text (backend / precision / mode), never by colour alone.
The lower panels show left minus right at the shared sample times with the reviewed audit tolerance as a band, so a
reader sees both whether the runs differ and whether the difference matters.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from rubric import CaseComparison, CaseResult, ContactCase
from rubric.discrepancy import ArrayDiff, shared_indices, side_label

from .common import CASE_COLORS, finish, new_figure, safe_name

# Left: solid line with round markers; right: dashed line with crosses. The colours only repeat the distinction.
STYLES = (dict(ls="-", marker="o", ms=3, mfc="none", lw=1.6, color=CASE_COLORS[0]),
          dict(ls="--", marker="x", ms=4, lw=1.3, color=CASE_COLORS[1]))
CONTACT_PANELS = (("z", "cube centre height z (m)"), ("vz", "vertical velocity vz (m/s)"),
                  ("contact_count", "contact count (cube\u2013table)"))
LANE_PANELS = (("x", "position x (m)"), ("vx", "velocity vx (m/s)"))


def draw_comparison(left: CaseResult, right: CaseResult, comparison: CaseComparison, out_dir: Path) -> list[Path]:
    """The comparison's figures: one for a contact case (z, vz, contacts), one per lane for a friction case (x, vx)."""
    out_dir = Path(out_dir)
    stem = f"audit_{comparison.case}_{_tag(left)}_vs_{_tag(right)}"
    if isinstance(left.spec, ContactCase):
        panels = [(name, name, label) for name, label in CONTACT_PANELS]
        return [_figure(left, right, comparison, panels, out_dir / f"{safe_name(stem)}.png", subject="falling cube")]
    paths = []
    for lane in left.spec.lanes:
        panels = [(f"{lane.name}_{name}", name, label) for name, label in LANE_PANELS]
        path = out_dir / f"{safe_name(f'{stem}_{lane.name}')}.png"
        paths.append(_figure(left, right, comparison, panels, path, subject=f"lane '{lane.name}'"))
    return paths


def _tag(r: CaseResult) -> str:
    return side_label(r).replace(" / ", "-")


def _figure(left: CaseResult, right: CaseResult, c: CaseComparison, panels, path: Path, *, subject: str) -> Path:
    fig = new_figure(5.2 * len(panels), 7.5)
    axes = fig.subplots(2, len(panels), sharex=True, gridspec_kw={"height_ratios": (1.6, 1)})
    il, ir = shared_indices(left, right)
    diffs = {d.name: d for d in c.arrays}
    for col, (key, short, label) in enumerate(panels):
        top, bottom = axes[0, col], axes[1, col]
        for r, style in zip((left, right), STYLES):
            draw = top.step if short == "contact_count" else top.plot
            kwargs = dict(where="post") if short == "contact_count" else {}
            draw(r.arrays["t"], r.arrays[key], label=side_label(r), markevery=_every(r), **style, **kwargs)
        top.set_ylabel(label)
        top.legend(fontsize=8, loc="best", title="line style = run", title_fontsize=8)
        _difference(bottom, left.arrays["t"][il], left.arrays[key][il].astype(float) - right.arrays[key][ir].astype(float),
                    diffs.get(key), short)
        bottom.set_xlabel("simulated time t (s)")
        for ax in (top, bottom):
            ax.grid(alpha=0.3)
    axes_text = ", ".join(f"{axis} {' vs '.join(values)}" for axis, values in c.axes.items()) or "no axis differs (repeat)"
    fig.suptitle(f"{c.classification.upper().replace('_', ' ')} \u2014 case {c.case}, {subject}: {axes_text}\n"
                 f"{c.left} (solid, \u25cb) vs {c.right} (dashed, \u00d7); tolerances {c.tolerances_version}",
                 fontsize=12)
    return finish(fig, [left, right], path, source="two measurements of one case spec",
                  notes=[f"classification: {c.classification}", c.summary])


def _every(r: CaseResult) -> int:
    """Markers on about 40 samples, so dense runs still show which run a line is."""
    return max(1, len(r.arrays["t"]) // 40)


def _difference(ax, t: np.ndarray, d: np.ndarray, record: ArrayDiff | None, short: str) -> None:
    ax.axhline(0.0, color="#888888", lw=0.8)
    if short == "contact_count":
        ax.step(t, d, where="post", color="k", lw=1.3, label="left \u2212 right")
    else:
        ax.plot(t, d, color="k", lw=1.2, marker=".", ms=3, label="left \u2212 right")
    if record is not None and record.max_abs is None:
        ax.set_title(f"{short}: the two records share no sample time", fontsize=9.5)
    elif record is not None:
        if record.tolerance_value > 0:
            ax.axhspan(-record.tolerance_value, record.tolerance_value, color="#56B4E9", alpha=0.25,
                       label=f"\u00b1 {record.tolerance_value:g} {record.unit} ({record.tolerance})")
        verdict = "bit-equal" if record.bit_equal else ("within" if record.within else "BEYOND tolerance")
        if 0 < record.max_abs and 1.3 * record.max_abs < record.tolerance_value:
            # Zoom to the difference itself: at the tolerance's scale a small difference would read as a flat zero.
            ax.set_ylim(-1.3 * record.max_abs, 1.3 * record.max_abs)
            verdict += f"; y zoomed, band edge \u00b1{record.tolerance_value:g} off-scale"
        ax.set_title(f"{short}: max |\u0394| {record.max_abs:.3g}, rms {record.rms:.3g} {record.unit}\n{verdict}",
                     fontsize=9.5)
    ax.set_ylabel(f"\u0394 {short} at shared times")
    ax.legend(fontsize=8, loc="best")
