"""Provenance guards on real measurements: another Genesis than the rubric pins, or another backend than asked,
makes a result ungradable, with the reason, its evidence kept."""

from __future__ import annotations

from dataclasses import replace

from rubric import load_rubric
from rubric.guards import gradable, provenance_violation


def _with_provenance(result, **changes):
    return replace(result, provenance=result.provenance.model_copy(update=changes))


def test_a_measurement_on_the_pinned_engine_and_requested_backend_is_gradable(measured):
    rubric = load_rubric("L03", "2")
    assert measured["N1"].provenance.versions["genesis"] == rubric.engine_version == "1.3.3"
    assert provenance_violation(measured["N1"], rubric) is None
    assert gradable(measured, rubric) == measured


def test_another_genesis_version_is_a_violation_kept_with_its_arrays(measured):
    rubric = load_rubric("L03", "2")
    other = _with_provenance(measured["N1"], versions={**measured["N1"].provenance.versions, "genesis": "1.4.0"})
    reason = provenance_violation(other, rubric)
    assert reason is not None and "Genesis 1.4.0" in reason and "pins Genesis 1.3.3" in reason
    kept = gradable({"N1": other, "N2": measured["N2"]}, rubric)
    assert kept["N1"].status == "failed" and kept["N1"].error == reason
    assert kept["N1"].arrays is other.arrays and kept["N1"].provenance is other.provenance  # evidence kept
    assert kept["N2"] is measured["N2"]


def test_numbers_from_another_backend_than_requested_are_a_violation(measured):
    rubric = load_rubric("L03", "2")
    moved = _with_provenance(measured["N2"], actual_backend="cuda")
    assert "requested backend cpu but the numbers came from cuda" in provenance_violation(moved, rubric)


def test_a_failed_result_is_not_judged_again(measured):
    rubric = load_rubric("L03", "2")
    failed = replace(_with_provenance(measured["N1"], versions={"genesis": "0.1"}), status="failed", error="crash")
    assert provenance_violation(failed, rubric) is None


def test_grading_never_uses_a_violating_result_and_says_why(measured):
    from rubric import grade_sheet, parse_sheet
    from tests.factories import reference_sheet, sheet_results

    rubric = load_rubric("L03", "2")
    results = sheet_results(measured)
    results["N1"] = _with_provenance(measured["N1"], versions={**measured["N1"].provenance.versions, "genesis": "1.4.0"})
    report = grade_sheet(parse_sheet(reference_sheet()), results, rubric)
    lost = [i for i in report.items if i.verdict == "not_measured"]
    assert lost and report.total < report.max_total
    assert all("pins Genesis 1.3.3" in i.feedback for i in lost), [i.feedback for i in lost]
    assert {"A2"} <= {i.id for i in lost}  # the substeps comparison needs N1
