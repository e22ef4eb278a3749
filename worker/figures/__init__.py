"""L03 lab-report figures: contact trajectories, clearance, friction lanes and camera frames or schematics, as PNGs.

Every function writes into a caller-given output folder (never the repository) and returns the paths it wrote.
Figures are built on `matplotlib.figure.Figure` with the Agg canvas, so no pyplot global state leaks between calls
or threads. Each figure names its cases, backend and engine version in a footer: a PNG copied out of its report
must still say where its numbers came from. Numbers drawn (stops, pair frictions, separation, first contact) are
the run's stored metrics (rubric.metrics), computed once where the case ran.

Modules: common (canvas, footer, metrics), contact (Part A), friction (Part B), frames (camera or schematic).
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

from rubric import CaseResult, FrictionCase

from .common import CAMERA_TITLE, DPI, SCHEMATIC_TITLE, provenance_line
from .contact import clearance_figure, contact_figures, contact_trajectory_figure
from .frames import frames_figure, has_frames
from .friction import friction_comparison_figure, friction_figure, stop_note


def lab_figures(results: Mapping[str, CaseResult], out_dir: str | Path, *,
                baseline: str = "friction-baseline") -> list[Path]:
    """Every L03 figure the results support: contact, per friction run, frames, and the baseline compared with
    every other friction run (the lab's table-0.30 run, a student's own table exercise, the colour-swapped control),
    whatever each is named."""
    out_dir = Path(out_dir)
    paths = contact_figures(results, out_dir)
    friction = [r for r in results.values() if isinstance(r.spec, FrictionCase)]
    paths += [friction_figure(r, out_dir) for r in friction]
    if baseline in results:
        paths += [friction_comparison_figure(results[baseline], r, out_dir)
                  for r in friction if r.spec.name != baseline]
    paths += [frames_figure(r, out_dir) for r in results.values()]
    return paths


__all__ = [
    "CAMERA_TITLE",
    "DPI",
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
    "stop_note",
]
