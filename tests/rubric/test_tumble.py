"""The tumble rule on synthetic orientations, where the right answer follows from the geometry by construction."""

import math

import numpy as np
import pytest

from rubric import get_case, lane_metrics, parse_metrics
from rubric.metrics import TUMBLE_EXPLANATION, tumble_angle_deg, tumbled


def _about_y(angles_deg) -> np.ndarray:
    """Quaternions (w, x, y, z) of rotations about the world y axis (a cube pitching forward over its front edge)."""
    half = np.radians(np.asarray(angles_deg, dtype=float)) / 2
    return np.stack([np.cos(half), np.zeros_like(half), np.sin(half), np.zeros_like(half)], axis=1)


def _about_z(angles_deg) -> np.ndarray:
    half = np.radians(np.asarray(angles_deg, dtype=float)) / 2
    return np.stack([np.cos(half), np.zeros_like(half), np.zeros_like(half), np.sin(half)], axis=1)


def _friction_arrays(spec, quats: dict[str, np.ndarray | None]) -> dict[str, np.ndarray]:
    """A friction run's arrays: each lane slides 0.3 m and stops; only its orientation differs between tests."""
    n = spec.sample_count
    t = np.arange(n) * spec.dt
    x = spec.start_x + 0.3 * (1 - np.exp(-t / 0.1))
    vx = np.gradient(x, t)
    vx[t > 0.8] = 0.0
    arrays = {"t": t}
    for lane in spec.lanes:
        p = lane.name
        arrays |= {
            f"{p}_x": x, f"{p}_y": np.full(n, lane.y), f"{p}_z": np.full(n, spec.rest_z), f"{p}_vx": vx,
            f"{p}_omega": np.zeros((n, 3)), f"{p}_contact_count": np.full(n, 4, dtype=np.int32),
            f"{p}_contact_friction": np.full(n, max(spec.table.friction, lane.friction)),
            f"{p}_table_friction": np.array(spec.table.friction), f"{p}_cube_friction": np.array(lane.friction),
        }
        if quats.get(p) is not None:
            arrays[f"{p}_quat"] = quats[p]
    return arrays


def _ramp(n: int, peak: float, end: float) -> np.ndarray:
    """Tilt rising to `peak` degrees halfway through the run, then settling at `end` degrees."""
    half = n // 2
    return np.r_[np.linspace(0.0, peak, half), np.linspace(peak, end, n - half)]


def test_the_tip_over_angle_comes_from_the_geometry():
    # A cube balances on an edge when its centre is straight above it: atan(1) = 45 degrees.
    assert tumble_angle_deg(0.08, 0.08) == pytest.approx(45.0)
    # A tall, narrow box tips over sooner; a flat one needs more: the rule is geometry, not a tuned number.
    assert tumble_angle_deg(0.04, 0.16) == pytest.approx(math.degrees(math.atan(0.25)))
    assert tumble_angle_deg(0.16, 0.04) == pytest.approx(math.degrees(math.atan(4.0)))
    assert not tumbled(44.9, width=0.08, height=0.08) and tumbled(45.1, width=0.08, height=0.08)


def test_a_cube_that_rocks_back_onto_its_face_did_not_tumble_and_one_that_falls_over_did():
    spec = get_case("friction-baseline")
    n = spec.sample_count
    # low rocks up to 35 degrees and comes back to its face; high tips past 45 and lands on the next face (90).
    arrays = _friction_arrays(spec, {"low": _about_y(_ramp(n, 35.0, 0.0)), "high": _about_y(_ramp(n, 90.0, 90.0))})
    low, high = (lane_metrics(spec, arrays, lane) for lane in ("low", "high"))
    assert low.max_tilt_deg == pytest.approx(35.0, abs=1e-6) and low.tumbled is False
    assert high.max_tilt_deg == pytest.approx(90.0, abs=1e-6) and high.tumbled is True


def test_a_cube_that_rolls_over_twice_still_counts_as_tumbled():
    # Two faces over (180 degrees): the cube's z axis points down again, so only the maximum over the run sees it.
    spec = get_case("friction-baseline")
    n = spec.sample_count
    arrays = _friction_arrays(spec, {"low": _about_y(np.linspace(0.0, 180.0, n)), "high": _about_y(np.zeros(n))})
    low = lane_metrics(spec, arrays, "low")
    assert low.tumbled is True and low.max_tilt_deg == pytest.approx(90.0, abs=0.5)
    assert lane_metrics(spec, arrays, "high").tumbled is False


def test_spinning_flat_on_the_table_is_not_tumbling():
    # Yaw keeps the bottom face on the table: however far the cube turns about the vertical, it never tips.
    spec = get_case("friction-baseline")
    n = spec.sample_count
    arrays = _friction_arrays(spec, {"low": _about_z(np.linspace(0.0, 720.0, n)), "high": _about_z(np.zeros(n))})
    low = lane_metrics(spec, arrays, "low")
    assert low.max_tilt_deg == pytest.approx(0.0, abs=1e-4) and low.tumbled is False


def test_a_run_recorded_without_orientation_says_so_instead_of_guessing():
    spec = get_case("friction-baseline")
    low = lane_metrics(spec, _friction_arrays(spec, {}), "low")
    assert low.max_tilt_deg is None and low.tumbled is None


def test_metrics_stored_before_the_tumble_fields_still_parse():
    spec = get_case("friction-baseline")
    n = spec.sample_count
    arrays = _friction_arrays(spec, {"low": _about_y(np.zeros(n)), "high": _about_y(np.zeros(n))})
    stored = {"kind": "friction", "case": spec.name,
              "lanes": {lane: lane_metrics(spec, arrays, lane).model_dump(exclude={"max_tilt_deg", "tumbled"})
                        for lane in ("low", "high")}}
    old = parse_metrics(stored)
    assert old.lane("low").max_tilt_deg is None and old.lane("low").tumbled is None


def test_the_explanation_is_one_sentence_about_the_stop():
    assert TUMBLE_EXPLANATION.count(". ") == 0 and TUMBLE_EXPLANATION.endswith(".")
    assert "not a sliding stop" in TUMBLE_EXPLANATION
