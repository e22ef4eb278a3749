"""What every figure shares: canvas, colours, file names, the provenance footer and the stored metrics."""

from __future__ import annotations

import re
from collections.abc import Iterable
from pathlib import Path

from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from rubric import CaseResult, ContactCase, case_metrics
from rubric.metrics import ContactMetrics, FrictionMetrics

DPI = 110
# Distinct, colour-blind-friendly case colours (Okabe-Ito); lanes use their own Surface colour instead.
CASE_COLORS = ("#0072B2", "#D55E00", "#009E73", "#CC79A7", "#E69F00", "#56B4E9", "#000000")
CAMERA_TITLE = "Genesis camera"
SCHEMATIC_TITLE = "SCHEMATIC drawn from measured positions \u2014 rendering SKIP, not a camera image"
# Seconds shown before / after first contact in the zoomed contact panels.
ZOOM_BEFORE_S, ZOOM_AFTER_S = 0.05, 0.30
COUNT_OFFSET = 0.07
FOOTER_IN = 0.3


def new_figure(width: float, height: float) -> Figure:
    fig = Figure(figsize=(width, height), dpi=DPI, layout="constrained")
    FigureCanvasAgg(fig)
    # Reserve a strip at the bottom for the provenance footer; constrained layout ignores free-floating text.
    strip = FOOTER_IN / height
    fig.get_layout_engine().set(rect=(0.0, strip, 1.0, 1.0 - strip))
    return fig


def safe_name(name: str) -> str:
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


def finish(fig: Figure, results: list[CaseResult], path: Path, *, source: str, skipped: list[str] = (),
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


def split_ok(results: Iterable[CaseResult]) -> tuple[list[CaseResult], list[str]]:
    results = list(results)
    return [r for r in results if r.ok and r.arrays], [r.spec.name for r in results if not (r.ok and r.arrays)]


def metrics_of(result: CaseResult) -> ContactMetrics | FrictionMetrics:
    """The metrics stored with a run (computed once where it ran); recomputed only for results made in memory."""
    return result.metrics if result.metrics is not None else case_metrics(result.spec, result.arrays)


def lane_color(lane) -> tuple[float, float, float]:
    return tuple(lane.color)


def case_label(spec: ContactCase) -> str:
    return f"{spec.name}: dt={spec.dt:g} s, substeps={spec.substeps} (substep_dt={spec.substep_dt:.4g} s)"
