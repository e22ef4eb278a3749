"""Acceptance rules of the parent process, on hand-made case folders (no Genesis needed to test the checks)."""

import numpy as np
import pytest

from rubric import get_case, with_backend
from rubric.results import spec_discretization
from tests.factories import contact_arrays, provenance, write_case_folder
from worker import load_result

N3 = get_case("N3")


def test_a_well_formed_folder_is_accepted(tmp_path):
    write_case_folder(tmp_path, contact_arrays(), provenance(N3))
    assert load_result(N3, tmp_path, exit_status=0, mode="isolated").ok


def test_non_finite_state_is_refused_naming_the_first_bad_sample(tmp_path):
    arrays = contact_arrays()
    arrays["z"][37:] = np.nan
    write_case_folder(tmp_path, arrays, provenance(N3))
    result = load_result(N3, tmp_path, exit_status=0, mode="isolated")
    assert result.status == "invalid"
    assert "z: first non-finite value at sample 37 (t=0.7600 s)" in result.error
    assert np.isnan(result.arrays["z"][37])  # the evidence is kept, not discarded


def test_wrong_length_and_a_provenance_for_another_requested_backend_are_refused(tmp_path):
    arrays = contact_arrays(n=150)  # N1's length for an N3 spec
    write_case_folder(tmp_path, arrays, provenance(N3, actual_backend="cpu", requested_backend="rocm"))
    result = load_result(N3, tmp_path, exit_status=0, mode="isolated")
    assert result.status == "invalid"
    assert "z: shape (150,), expected (75,)" in result.error
    assert "provenance.requested_backend: 'rocm', expected 'cpu'" in result.error


@pytest.mark.parametrize(("requested", "actual", "hip"), [
    ("cuda", "cpu", None),  # a GPU request that silently fell back to the CPU
    ("rocm", "cpu", "6.2.41133"),  # the same on a HIP build of torch, so only the backend is wrong
    ("cpu", "cuda", None),  # numbers from another device than the queue promised
])
def test_an_actual_backend_other_than_the_requested_one_is_refused(tmp_path, requested, actual, hip):
    spec = with_backend(N3, backend=requested)
    write_case_folder(tmp_path, contact_arrays(), provenance(spec, actual_backend=actual, torch_hip=hip))
    result = load_result(spec, tmp_path, exit_status=0, mode="isolated")
    assert result.status == "invalid" and result.metrics is None
    # The request itself was recorded faithfully: the actual backend is the one and only reason for refusal.
    assert result.error == f"provenance.actual_backend: {actual!r}, expected {requested!r}"


def test_a_rocm_result_without_a_hip_build_of_torch_is_refused(tmp_path):
    spec = with_backend(N3, backend="rocm")
    write_case_folder(tmp_path, contact_arrays(), provenance(spec, torch_device="cuda:0", torch_hip=None))
    result = load_result(spec, tmp_path, exit_status=0, mode="isolated")
    assert result.status == "invalid"
    assert result.error == "provenance.torch_hip: a ROCm result must come from a HIP build of torch"


def test_a_rocm_result_from_a_hip_build_of_torch_is_accepted(tmp_path):
    # The control for the refusals above: the same folder is fine once torch is a HIP build.
    spec = with_backend(N3, backend="rocm")
    write_case_folder(tmp_path, contact_arrays(), provenance(spec, torch_device="cuda:0", torch_hip="6.2.41133"))
    result = load_result(spec, tmp_path, exit_status=0, mode="isolated")
    assert result.ok, result.error
    assert result.provenance.actual_backend == "rocm" and result.provenance.torch_hip == "6.2.41133"


def test_a_frame_where_rendering_was_disabled_is_refused(tmp_path):
    arrays = contact_arrays()
    arrays["frame_final"] = np.full((4, 4, 3), 7, np.uint8)
    write_case_folder(tmp_path, arrays, provenance(N3))
    result = load_result(N3, tmp_path, exit_status=0, mode="isolated")
    assert "frame_final: rendering disabled but a non-empty frame was returned" in result.error


def test_a_killed_process_is_a_timeout_result_with_its_output(tmp_path):
    (tmp_path / "stdout.txt").write_text("half a run")
    result = load_result(N3, tmp_path, exit_status=None, mode="isolated", timeout_s=5)
    assert result.status == "timeout" and "5 s time limit" in result.error and result.stdout == "half a run"


def test_an_engine_discretization_that_differs_from_the_spec_is_refused(tmp_path):
    reported = spec_discretization(N3).model_dump() | {"substeps": 2, "internal_updates": 150}
    write_case_folder(tmp_path, contact_arrays(), provenance(N3, discretization=reported))
    result = load_result(N3, tmp_path, exit_status=0, mode="isolated")
    assert result.status == "invalid"
    assert "provenance.discretization.substeps: engine reported 2, the spec derives 1" in result.error
    assert "provenance.discretization.internal_updates: engine reported 150, the spec derives 75" in result.error


def test_a_time_axis_that_is_not_the_engine_dt_is_refused(tmp_path):
    arrays = contact_arrays()
    arrays["t"] = np.linspace(0.02, 1.5, 75) ** 1.01  # uneven spacing: not what a dt=0.02 engine sampled
    write_case_folder(tmp_path, arrays, provenance(N3))
    result = load_result(N3, tmp_path, exit_status=0, mode="isolated")
    assert result.status == "invalid" and "t: sample spacing" in result.error and "engine dt 0.02 s" in result.error


def test_a_process_that_died_with_its_traceback_on_stdout_is_failed_quoting_it(tmp_path):
    """As seen on a GPU host whose image lacked libGL: the import error reached stdout only."""
    (tmp_path / "stdout.txt").write_text("Traceback (most recent call last):\n  ...\nImportError: libGL.so.1: cannot "
                                         "open shared object file\n")
    (tmp_path / "stderr.txt").write_text("")
    result = load_result(N3, tmp_path, exit_status=1, mode="isolated")
    assert result.status == "failed"
    assert result.error == ("case process failed (exit 1): no output on stderr; stdout ends: ImportError: libGL.so.1: "
                            "cannot open shared object file")
