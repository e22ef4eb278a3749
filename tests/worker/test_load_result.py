"""Acceptance rules of the parent process, on hand-made case folders (no Genesis needed to test the checks)."""

import json

import numpy as np

from rubric import get_case
from rubric.results import spec_discretization
from worker import load_result


def _write(out, arrays, provenance):
    np.savez(out / "arrays.npz", **arrays)
    (out / "provenance.json").write_text(json.dumps(provenance))


def _provenance(**over):
    p = {
        "case": "N3", "requested_backend": "cpu", "actual_backend": "cpu", "torch_device": "cpu",
        "device_name": "test cpu", "torch_hip": None, "torch_cuda": None, "versions": {"genesis": "1.3.3"},
        "precision": "32", "seed": 0, "deterministic_algorithms": False, "execution_mode": "isolated",
        "host": "h", "pid": 1, "timings": {"import_s": 1, "init_s": 1, "build_s": 1, "steps_s": 1},
        "rendering": {"requested": False, "status": "SKIP", "frames": 0, "detail": "off"},
        "runner_version": "2", "exit_status": 0,
        # What the engine reports for N3 when it ran as specified.
        "discretization": spec_discretization(get_case("N3")).model_dump(),
    }
    return p | over


def _arrays(n=75):
    return {
        "t": np.arange(1, n + 1) * 0.02, "z": np.full(n, 0.77), "vz": np.zeros(n),
        "contact_count": np.zeros(n, dtype=np.int32), "clearance": np.zeros(n), "quat": np.tile([1.0, 0, 0, 0], (n, 1)),
        "frame_initial": np.zeros((0, 0, 3), np.uint8), "frame_final": np.zeros((0, 0, 3), np.uint8),
    }


def test_a_well_formed_folder_is_accepted(tmp_path):
    _write(tmp_path, _arrays(), _provenance())
    assert load_result(get_case("N3"), tmp_path, exit_status=0, mode="isolated").ok


def test_non_finite_state_is_refused_naming_the_first_bad_sample(tmp_path):
    arrays = _arrays()
    arrays["z"][37:] = np.nan
    _write(tmp_path, arrays, _provenance())
    result = load_result(get_case("N3"), tmp_path, exit_status=0, mode="isolated")
    assert result.status == "invalid"
    assert "z: first non-finite value at sample 37 (t=0.7600 s)" in result.error
    assert np.isnan(result.arrays["z"][37])  # the evidence is kept, not discarded


def test_wrong_length_and_backend_mismatch_are_refused(tmp_path):
    arrays = _arrays(n=150)  # N1's length for an N3 spec
    _write(tmp_path, arrays, _provenance(actual_backend="cpu", requested_backend="rocm"))
    result = load_result(get_case("N3"), tmp_path, exit_status=0, mode="isolated")
    assert result.status == "invalid"
    assert "z: shape (150,), expected (75,)" in result.error
    assert "provenance.requested_backend: 'rocm', expected 'cpu'" in result.error


def test_a_frame_where_rendering_was_disabled_is_refused(tmp_path):
    arrays = _arrays()
    arrays["frame_final"] = np.full((4, 4, 3), 7, np.uint8)
    _write(tmp_path, arrays, _provenance())
    result = load_result(get_case("N3"), tmp_path, exit_status=0, mode="isolated")
    assert "frame_final: rendering disabled but a non-empty frame was returned" in result.error


def test_a_killed_process_is_a_timeout_result_with_its_output(tmp_path):
    (tmp_path / "stdout.txt").write_text("half a run")
    result = load_result(get_case("N3"), tmp_path, exit_status=None, mode="isolated", timeout_s=5)
    assert result.status == "timeout" and "5 s time limit" in result.error and result.stdout == "half a run"


def test_an_engine_discretization_that_differs_from_the_spec_is_refused(tmp_path):
    reported = spec_discretization(get_case("N3")).model_dump() | {"substeps": 2, "internal_updates": 150}
    _write(tmp_path, _arrays(), _provenance(discretization=reported))
    result = load_result(get_case("N3"), tmp_path, exit_status=0, mode="isolated")
    assert result.status == "invalid"
    assert "provenance.discretization.substeps: engine reported 2, the spec derives 1" in result.error
    assert "provenance.discretization.internal_updates: engine reported 150, the spec derives 75" in result.error


def test_a_time_axis_that_is_not_the_engine_dt_is_refused(tmp_path):
    arrays = _arrays()
    arrays["t"] = np.linspace(0.02, 1.5, 75) ** 1.01  # uneven spacing: not what a dt=0.02 engine sampled
    _write(tmp_path, arrays, _provenance())
    result = load_result(get_case("N3"), tmp_path, exit_status=0, mode="isolated")
    assert result.status == "invalid" and "t: sample spacing" in result.error and "engine dt 0.02 s" in result.error
