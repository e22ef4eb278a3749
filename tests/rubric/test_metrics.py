"""Metric definitions on small synthetic trajectories, where the right answer is known by construction."""

import numpy as np
import pytest

from rubric import align, contact_metrics, effective_pair_friction, get_case, sustained_stop
from rubric.metrics import penetration_proxy, separation_mask, tilt


def test_sustained_stop_needs_a_full_hold_interval():
    t = np.arange(10) * 0.1
    x = np.arange(10.0)
    vx = np.array([1.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0])
    # One dip to zero at sample 1 is a crossing, not a stop: the first full interval starts at sample 4.
    stop = sustained_stop(t, x, vx, stop_speed=0.5, hold_steps=3)
    assert (stop.stopped, stop.index, stop.time, stop.distance) == (True, 4, pytest.approx(0.4), 4.0)


def test_no_stop_is_reported_instead_of_using_the_final_sample():
    t = np.arange(10) * 0.1
    vx = np.r_[np.ones(8), 0.0, 0.0]  # slow only at the very end: the hold interval does not fit
    stop = sustained_stop(t, np.arange(10.0), vx, stop_speed=0.5, hold_steps=4)
    assert not stop.stopped and stop.distance is None
    assert "not stopped within the measured window" in stop.detail


def test_pair_friction_follows_the_pinned_engine_rule_including_edge_cases():
    assert effective_pair_friction(0.5, 0.1) == 0.5
    assert effective_pair_friction(0.3, 0.8) == 0.8
    assert effective_pair_friction(0.5, 0.5) == 0.5
    # Runtime friction ratios scale each side before the max ...
    assert effective_pair_friction(0.5, 0.8, ratio_b=0.5) == pytest.approx(0.5)
    assert effective_pair_friction(0.5, 0.8, ratio_a=2.0) == pytest.approx(1.0)
    # ... and the result never falls below the engine's floor of 0.01.
    assert effective_pair_friction(0.02, 0.02, ratio_a=0.1, ratio_b=0.1) == 0.01


def _contact_arrays(z, vz, count, spec):
    n = len(z)
    z = np.asarray(z, dtype=float)
    return {
        "t": np.arange(1, n + 1) * spec.dt,
        "z": z,
        "vz": np.asarray(vz, dtype=float),
        "contact_count": np.asarray(count, dtype=np.int32),
        "clearance": z - spec.cube.size / 2 - spec.table.top_z,
        "quat": np.tile([1.0, 0.0, 0.0, 0.0], (n, 1)),
    }


def test_separation_needs_no_contact_and_positive_clearance_after_first_contact():
    spec = get_case("N1").model_copy(update={"duration": 0.08})  # 8 samples
    rest = spec.expected_center_z
    z = [rest + 0.2, rest - 0.01, rest + 0.005, rest + 0.0005, rest, rest, rest, rest]
    vz = [-2.0, -0.5, 0.3, 0.1, 0.0, 0.0, 0.0, 0.0]
    count = [0, 4, 0, 0, 4, 4, 4, 4]
    m = contact_metrics(spec, _contact_arrays(z, vz, count, spec))
    assert m.first_contact_index == 1
    # Sample 0 is before contact (free fall is not "separation"); sample 3 has no contact but only 0.5 mm clearance,
    # under the declared 1 mm tolerance: only sample 2 counts.
    assert m.separation_samples == 1
    assert m.separation_duration == pytest.approx(spec.dt)
    assert m.penetration_proxy == pytest.approx(0.01)
    assert m.max_upward_velocity_after_contact == pytest.approx(0.3)
    assert m.upward_samples_after_contact == 2
    assert not m.passed_through


def test_penetration_proxy_is_never_negative_and_tilt_detects_rotation():
    assert penetration_proxy(np.array([1.0, 0.9]), 0.765) == 0.0
    half = np.sqrt(0.5)
    angles = tilt(np.array([[1.0, 0, 0, 0], [half, half, 0, 0], [half, 0, 0, half]]))
    assert angles == pytest.approx([0.0, np.pi / 2, 0.0])  # yaw keeps the bottom face flat


def test_alignment_compares_only_shared_sample_times():
    a = {"t": np.arange(1, 151) * 0.01, "z": np.arange(150.0), "vz": np.zeros(150)}
    b = {"t": np.arange(1, 76) * 0.02, "z": np.arange(1, 151, 2.0) + 0.5, "vz": np.zeros(75)}
    result = align("A", a, "B", b)
    assert result.shared_samples == 75
    assert result.first_shared_times == [0.02, 0.04, 0.06]
    assert result.max_abs_diff["z"] == pytest.approx(0.5)


def test_separation_mask_ignores_samples_before_first_contact():
    spec = get_case("N1")
    arrays = {
        "contact_count": np.array([0, 0, 4, 0, 0, 4]),
        "clearance": np.array([0.2, 0.1, 0.0, 0.005, 0.0005, 0.0]),
    }
    # Sample 0-1: falling, not separation. Sample 3: no contact and clearance above 1 mm. Sample 4: within tolerance.
    assert separation_mask(spec, arrays).tolist() == [False, False, False, True, False, False]
