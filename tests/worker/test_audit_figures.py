"""lessons.l03.figures.audit (a backend audit's figures, drawn through worker.figures.draw_comparison) on real Genesis results: both runs overlaid with their difference, as decodable PNGs in the
output folder, each run named by its backend / precision / mode and the classification in the title."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import matplotlib.image as mpimg
import numpy as np
import pytest
from PIL import Image

from rubric import compare_cases
from worker.figures import draw_comparison  # the service's way: by the lesson declaring the runs' kind

pytestmark = pytest.mark.slow

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
REPO = Path(__file__).resolve().parents[2]


def isolated_twin(result, **shifted):
    """The measured run as if a second, isolated run had measured it, with `shifted` arrays offset (a discrepancy)."""
    arrays = {k: (v + shifted[k] if k in shifted else v) for k, v in result.arrays.items()}
    return dataclasses.replace(result, arrays=arrays,
                               provenance=result.provenance.model_copy(update={"execution_mode": "isolated"}))


def check_png(path: Path, out_dir: Path) -> np.ndarray:
    assert path.is_file() and path.parent == out_dir
    assert REPO not in path.resolve().parents, f"{path} was written into the repository"
    assert path.read_bytes()[:8] == PNG_SIGNATURE
    pixels = mpimg.imread(path)
    assert pixels.ndim == 3 and pixels.shape[0] > 400 and pixels.shape[1] > 800
    assert pixels.std() > 0.05, f"{path.name} is blank"
    return pixels


def test_a_contact_comparison_is_one_png_titled_with_its_classification(measured, tmp_path):
    left = measured["N1"]
    right = isolated_twin(left, z=2e-5)  # beyond height_abs: numeric drift, and the figure must say so
    comparison = compare_cases(left, right)
    assert comparison.classification == "numeric_drift"
    paths = draw_comparison(left, right, comparison, tmp_path)
    assert [p.name for p in paths] == ["audit_N1_cpu-32-bit-warm_vs_cpu-32-bit-isolated.png"]
    check_png(paths[0], tmp_path)
    meta = Image.open(paths[0]).text
    assert meta["Title"].startswith("NUMERIC DRIFT")
    assert "cpu / 32-bit / warm (solid" in meta["Title"] and "cpu / 32-bit / isolated (dashed" in meta["Title"]
    assert "classification: numeric_drift" in meta["Description"] and comparison.summary in meta["Description"]


def test_a_friction_comparison_draws_one_png_per_lane(measured, tmp_path):
    left = measured["friction-baseline"]
    right = isolated_twin(left)
    comparison = compare_cases(left, right)
    assert comparison.classification == "identical"
    paths = draw_comparison(left, right, comparison, tmp_path)
    assert [p.name for p in paths] == [f"audit_friction-baseline_cpu-32-bit-warm_vs_cpu-32-bit-isolated_{lane}.png"
                                       for lane in ("low", "high")]
    for path in paths:
        check_png(path, tmp_path)
        assert Image.open(path).text["Title"].startswith("IDENTICAL")
