"""Figures as PNGs, drawn by the lesson that owns the cases (rubric.lesson.Lesson.figures names its module, e.g.
lessons/l03/figures): a grader check's offline report (`lab_figures`) and a backend audit's comparison of two runs
(`draw_comparison`). The lesson is the one that declares the results' case kind (rubric.lesson.lesson_of_kind).
Here: the dispatch and `cache` (a figure drawn once per distinct input, copied after), which any lesson's figures use.
Matplotlib loads with the lesson's module, only where figures are drawn."""

from __future__ import annotations

import importlib
from collections.abc import Mapping
from pathlib import Path
from types import ModuleType

from rubric import CaseResult
from rubric.lesson import lesson_of_kind

from .cache import FigureCache


def figures_of(kind: str) -> ModuleType:
    """The figures module of the lesson declaring case kind `kind`; LookupError where it declares none."""
    declared = lesson_of_kind(kind)
    if not declared.figures:
        raise LookupError(f"lesson {declared.name} declares no figures")
    return importlib.import_module(declared.figures)


def lab_figures(results: Mapping[str, CaseResult], out_dir: str | Path, *, cache: FigureCache | None = None,
                **options) -> list[Path]:
    """Every figure the results support, by their lesson (none without results)."""
    if not results:
        return []
    kind = next(iter(results.values())).spec.kind
    if not lesson_of_kind(kind).figures:
        return []  # a lesson that declares no figures draws none (its report shows its conditions and numbers)
    return figures_of(kind).lab_figures(results, out_dir, cache=cache, **options)


def draw_comparison(a: CaseResult, b: CaseResult, comparison, folder: Path) -> list[Path]:
    """A backend audit's two runs of one case overlaid with their difference, by their lesson."""
    return figures_of(a.spec.kind).draw_comparison(a, b, comparison, folder)


__all__ = ["FigureCache", "draw_comparison", "figures_of", "lab_figures"]
