"""L03 lab-report figures: contact trajectories, clearance, friction lanes and camera frames or schematics, as PNGs.

Every function writes into a caller-given output folder (never the repository) and returns the paths it wrote.
Figures are built on `matplotlib.figure.Figure` with the Agg canvas, so no pyplot global state leaks between calls
or threads. Each figure names its cases, backend and engine version in a footer: a PNG copied out of its report
must still say where its numbers came from. Numbers drawn (stops, pair frictions, separation, first contact) are
the run's stored metrics (rubric.metrics), computed once where the case ran.

Modules: common (canvas, footer, metrics), contact (Part A), friction (Part B), frames (camera or schematic),
audit (a backend audit's two runs overlaid, `draw_comparison`). The service reaches them through L03's declaration
(rubric.l03: figures) and worker.figures; worker.figures.cache draws a figure once per distinct input.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

from rubric import CaseResult, ContactCase, FrictionCase

from worker.figures.cache import FigureCache

from .common import CAMERA_TITLE, DPI, SCHEMATIC_TITLE, provenance_line
from .contact import clearance_figure, contact_figures, contact_trajectory_figure
from .frames import frames_figure, has_frames
from .friction import friction_comparison_figure, friction_figure, stop_note


def draw_comparison(a, b, comparison, folder):
    """A backend audit's two runs of one case overlaid with their difference (lessons.l03.figures.audit)."""
    from .audit import draw_comparison as draw

    return draw(a, b, comparison, folder)


def lab_figures(results: Mapping[str, CaseResult], out_dir: str | Path, *,
                baseline: str = "friction-baseline", cache: FigureCache | None = None) -> list[Path]:
    """Every L03 figure the results support: contact, per friction run, frames, and the baseline compared with
    every other friction run (the lab's table-0.30 run, a student's own table exercise, the colour-swapped control),
    whatever each is named. With a cache, a figure whose inputs were drawn before is copied, not drawn."""
    out_dir = Path(out_dir)
    cache = cache or FigureCache(None)
    paths = []
    contact = [r for r in results.values() if isinstance(r.spec, ContactCase)]
    if contact:
        paths += [
            cache.figure("contact_trajectories", contact, out_dir,
                         lambda: contact_trajectory_figure(contact, out_dir / "contact_trajectories.png")),
            cache.figure("contact_clearance", contact, out_dir,
                         lambda: clearance_figure(contact, out_dir / "contact_clearance.png")),
        ]
    friction = [r for r in results.values() if isinstance(r.spec, FrictionCase)]
    paths += [cache.figure("friction", [r], out_dir, lambda r=r: friction_figure(r, out_dir)) for r in friction]
    if baseline in results:
        base = results[baseline]
        paths += [cache.figure("friction_comparison", [base, r], out_dir,
                               lambda r=r: friction_comparison_figure(base, r, out_dir))
                  for r in friction if r.spec.name != baseline]
    paths += [cache.figure("frames", [r], out_dir, lambda r=r: frames_figure(r, out_dir)) for r in results.values()]
    return paths


__all__ = [
    "CAMERA_TITLE",
    "FigureCache",
    "DPI",
    "draw_comparison",
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
