"""worker.figures on real Genesis results: every figure is a valid, non-blank PNG in the output folder, says where
its numbers came from, and takes the camera path only when the run rendered."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import matplotlib.image as mpimg
import numpy as np
import pytest
from PIL import Image

from lessons.l03 import figures
from rubric import CONTACT_CASES, CaseResult, case_metrics, get_case

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
REPO = Path(__file__).resolve().parents[2]


def _png(path: Path) -> np.ndarray:
    """Decoded pixels of a PNG file, after checking its signature bytes."""
    assert path.read_bytes()[:8] == PNG_SIGNATURE, f"{path} is not a PNG"
    return mpimg.imread(path)


def _meta(path: Path) -> dict[str, str]:
    return Image.open(path).text


@pytest.fixture(scope="module")
def lab_pngs(measured, tmp_path_factory) -> dict[str, Path]:
    out = tmp_path_factory.mktemp("figures")
    return {p.name: p for p in figures.lab_figures(measured, out)}


def test_lab_figures_cover_every_part_of_the_lab(lab_pngs, measured):
    expected = {
        "contact_trajectories.png",
        "contact_clearance.png",
    } | {f"frames_{name}_schematic.png" for name in measured} | {
        # Every friction run gets its lane figure, the colour-swapped control included ...
        f"friction_{name}.png" for name, result in measured.items() if result.spec.kind == "friction"} | {
        # ... and every friction run other than the baseline is drawn against it.
        f"friction_compare_friction-baseline_vs_{name}.png" for name, result in measured.items()
        if result.spec.kind == "friction" and name != "friction-baseline"}
    assert {"friction_friction-baseline.png", "friction_friction-table-0.30.png",
            "friction_compare_friction-baseline_vs_friction-table-0.30.png",
            "friction_compare_friction-baseline_vs_friction-baseline-colors-swapped.png"} <= expected
    assert set(lab_pngs) == expected


def test_figures_stay_in_the_output_folder(lab_pngs, tmp_path_factory):
    for path in lab_pngs.values():
        assert path.is_file()
        assert REPO not in path.resolve().parents, f"{path} was written into the repository"


@pytest.mark.parametrize(
    "name, size_in",
    [
        ("contact_trajectories.png", (14, 9.5)),
        ("contact_clearance.png", (14, 8)),
        ("friction_friction-baseline.png", (12, 10)),
        ("friction_compare_friction-baseline_vs_friction-table-0.30.png", (13, 8.5)),
        ("frames_N1_schematic.png", (13, 5.0)),
    ],
)
def test_png_is_valid_with_the_declared_size(lab_pngs, name, size_in):
    pixels = _png(lab_pngs[name])
    height, width = pixels.shape[:2]
    assert (width, height) == (round(size_in[0] * figures.DPI), round(size_in[1] * figures.DPI))
    # Not a blank canvas: a real plot has many distinct grey levels.
    assert pixels[..., :3].std() > 0.05
    assert len(np.unique(pixels[..., :3].reshape(-1, 3), axis=0)) > 100


def test_every_figure_names_cases_backend_and_engine_version(lab_pngs, measured):
    for name, path in lab_pngs.items():
        description = _meta(path)["Description"]
        assert "backend: cpu" in description, name
        assert f"genesis {measured['N1'].provenance.versions['genesis']}" in description, name
    assert all(f"{case}" in _meta(lab_pngs["contact_trajectories.png"])["Description"] for case in CONTACT_CASES)


def test_schematic_path_when_frames_are_empty(lab_pngs, measured):
    for name, result in measured.items():
        assert not figures.has_frames(result)
        meta = _meta(lab_pngs[f"frames_{name}_schematic.png"])
        assert meta["Source"] == "schematic"
        assert figures.SCHEMATIC_TITLE in meta["Title"]


def test_friction_figure_marks_measured_stops(lab_pngs):
    description = _meta(lab_pngs["friction_friction-baseline.png"])["Description"]
    assert "low: stopped at t=" in description
    assert "high: stopped at t=" in description
    assert "NOT STOPPED" not in description


def test_friction_figure_says_not_stopped_when_the_lane_keeps_moving(measured, tmp_path):
    result = measured["friction-baseline"]
    arrays = dict(result.arrays)
    # A lane that never slows below the stop speed: the figure must say so, not invent a stop from the last sample.
    arrays["low_vx"] = np.full_like(arrays["low_vx"], 1.0)
    # Metrics are computed once where a run happened: a doctored run carries its doctored metrics.
    moving = dataclasses.replace(result, arrays=arrays, metrics=case_metrics(result.spec, arrays))
    path = figures.friction_figure(moving, tmp_path)
    _png(path)
    description = _meta(path)["Description"]
    assert "low: NOT STOPPED within the measured window" in description
    assert "high: stopped at t=" in description


def test_failed_case_is_named_not_silently_dropped(measured, tmp_path):
    broken = CaseResult(spec=get_case("N3"), status="failed", error="child exited 1")
    paths = figures.contact_figures([measured["N1"], broken], tmp_path)
    assert [p.name for p in paths] == ["contact_trajectories.png", "contact_clearance.png"]
    for path in paths:
        _png(path)
        assert "not drawn (no valid result): N3" in _meta(path)["Description"]
    schematic = figures.frames_figure(broken, tmp_path)
    assert _meta(schematic)["Source"] == "schematic"


def test_file_names_cannot_escape_the_output_folder(measured, tmp_path):
    spec = measured["friction-baseline"].spec.model_copy(update={"name": "../../evil name"})
    result = dataclasses.replace(measured["friction-baseline"], spec=spec)
    path = figures.friction_figure(result, tmp_path)
    assert path.resolve().parent == tmp_path.resolve()
    assert path.is_file() and path.name.startswith("friction_") and "/" not in path.name


@pytest.mark.slow
def test_camera_path_when_the_run_rendered(rendered_n1, tmp_path):
    result = rendered_n1  # N1 with render=True, isolated: the session's run (tests/conftest.py), test_case_process's too
    assert result.ok, result.error
    assert figures.has_frames(result)
    path = figures.frames_figure(result, tmp_path / "fig")
    assert path.name == "frames_N1_camera.png"
    meta = _meta(path)
    assert meta["Source"] == "camera"
    assert meta["Title"].startswith(figures.CAMERA_TITLE)
    assert "execution: isolated" in meta["Description"]
    pixels = _png(path)
    # The camera frames are drawn at full size at least once over: the figure is larger than one frame.
    frame = result.arrays["frame_initial"]
    assert pixels.shape[1] > frame.shape[1]


def test_a_tumbled_lane_is_named_in_words_on_its_figures(measured, lab_pngs, tmp_path):
    result = measured["friction-baseline"]
    assert "TUMBLED" not in _meta(lab_pngs["friction_friction-baseline.png"])["Description"]
    arrays = dict(result.arrays)
    # The low cube pitches over its front edge onto the next face (90 degrees) half-way through the run.
    n = len(arrays["t"])
    half = np.radians(np.r_[np.linspace(0.0, 90.0, n // 2), np.full(n - n // 2, 90.0)]) / 2
    arrays["low_quat"] = np.stack([np.cos(half), 0 * half, np.sin(half), 0 * half], axis=1)
    tipped = dataclasses.replace(result, arrays=arrays, metrics=case_metrics(result.spec, arrays))
    assert tipped.metrics.lane("low").tumbled and not tipped.metrics.lane("high").tumbled
    path = figures.friction_figure(tipped, tmp_path)
    _png(path)
    description = _meta(path)["Description"]
    assert "low: stopped at t=" in description and "TUMBLED (max tilt 90.0\u00b0): not a sliding stop" in description
    assert "high: stopped at t=" in description and description.count("TUMBLED") == 1


def test_a_cached_figure_is_the_drawn_figure_byte_for_byte_and_other_runs_are_drawn_anew(measured, tmp_path):
    from worker.figures import FigureCache

    results = {name: measured[name] for name in ("N1", "N2", "friction-baseline", "friction-table-0.30")}
    first = FigureCache(tmp_path / "cache")
    drawn = figures.lab_figures(results, tmp_path / "first", cache=first)
    assert (first.drawn, first.copied) == (len(drawn), 0)

    second = FigureCache(tmp_path / "cache")
    copied = figures.lab_figures(results, tmp_path / "second", cache=second)
    assert (second.drawn, second.copied) == (0, len(drawn))
    assert [p.name for p in copied] == [p.name for p in drawn]
    for a, b in zip(drawn, copied):
        assert a.read_bytes() == b.read_bytes(), a.name

    # Another table-friction run (other arrays under the same name) shares only the figures that do not show it.
    other = dataclasses.replace(measured["friction-baseline"], spec=measured["friction-baseline"].spec.model_copy(
        update={"name": "friction-table-0.30"}))
    third = FigureCache(tmp_path / "cache")
    figures.lab_figures(results | {"friction-table-0.30": other}, tmp_path / "third", cache=third)
    # Drawn anew: its friction figure, its comparison with the baseline, its frames schematic.
    assert (third.drawn, third.copied) == (3, len(drawn) - 3)
