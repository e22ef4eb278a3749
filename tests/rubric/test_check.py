"""The L03 verdict on real measurements: every lesson condition is evaluated, and a broken case names itself."""

import pytest

from rubric import get_case
from rubric.check import OutputLocation, evaluate
from worker import run_case

pytestmark = pytest.mark.slow

OUTPUTS_OK = OutputLocation(passed=True, evidence="test outputs under tmp")
LESSON_CONDITIONS = [
    "processes", "rendering", "arrays", "duration", "timing_table", "contact", "substeps_reduce_proxy",
    "n1_n4_agree", "multi_evidence", "friction_baseline", "table_friction_change", "outputs",
]


def _check_results(measured):
    return {name: measured[name] for name in ("N1", "N2", "N3", "N4", "friction-baseline", "friction-table-0.30")}


def test_baseline_measurements_pass_every_condition(measured):
    report = evaluate(_check_results(measured), outputs=OUTPUTS_OK)
    assert [c.id for c in report.conditions] == LESSON_CONDITIONS
    assert report.passed, report.render_text()
    assert report.render_text().endswith("L03 CHECK: PASSED")
    # The evidence is the measurement, printed: the relationships the lesson predicts, with their numbers.
    proxy = report.contact
    assert proxy["N2"].penetration_proxy < proxy["N1"].penetration_proxy
    assert proxy["N4"].penetration_proxy < proxy["N3"].penetration_proxy
    evidence = next(c.evidence for c in report.conditions if c.id == "substeps_reduce_proxy")
    assert f"N1 {proxy['N1'].penetration_proxy * 1000:.3f} mm -> N2 {proxy['N2'].penetration_proxy * 1000:.3f} mm" \
        in evidence


def test_collision_disabled_fails_the_contact_condition_by_name(measured, tmp_path):
    broken = get_case("N1").model_copy(update={"enable_collision": False})
    results = _check_results(measured) | {"N1": run_case(broken, tmp_path, mode="warm")}
    report = evaluate(results, outputs=OUTPUTS_OK)
    failed = {c.id for c in report.failed}
    assert not report.passed
    assert {"contact", "substeps_reduce_proxy"} <= failed
    assert "processes" not in failed and "duration" not in failed  # the run itself was fine; the physics was not
    text = report.render_text()
    assert "L03 CHECK: FAILED" in text
    assert "failed: the cube contacts the table in every case and does not pass through it" in text
    assert "N1: NO CONTACT reported" in text


def test_a_failed_case_fails_the_conditions_that_need_it(measured):
    from rubric import CaseResult

    lost = CaseResult(spec=get_case("friction-baseline"), status="failed", error="case process failed (exit 1): boom")
    report = evaluate(_check_results(measured) | {"friction-baseline": lost}, outputs=OUTPUTS_OK)
    failed = {c.id for c in report.failed}
    assert {"processes", "arrays", "friction_baseline", "table_friction_change"} <= failed
    assert "boom" in report.render_text()


def test_output_location_condition_is_reported(measured):
    report = evaluate(_check_results(measured), outputs=OutputLocation(passed=False, evidence="NOT ignored by git"))
    assert [c.id for c in report.failed] == ["outputs"]


def test_the_stored_outcome_is_the_verdict_line_and_every_condition(measured):
    from rubric.check import CheckOutcome, verdict_line

    report = evaluate(_check_results(measured), outputs=OUTPUTS_OK)
    outcome = report.outcome(notes={"rendering": "Service run: rendering off."})
    assert isinstance(outcome, CheckOutcome)
    assert outcome.passed and outcome.verdict_line == verdict_line(True) == "L03 CHECK: PASSED"
    assert [(c.id, c.title, c.passed) for c in outcome.conditions] == \
        [(c.id, c.title, c.passed) for c in report.conditions]
    assert outcome.rubric_version == report.rubric_version
    assert outcome.backends == {name: "cpu" for name in _check_results(measured)}
    rendering = next(c for c in outcome.conditions if c.id == "rendering")
    # A note is added to the evidence, never in place of it, and it cannot change a verdict.
    original = next(c for c in report.conditions if c.id == "rendering")
    assert rendering.evidence == original.evidence + "\nService run: rendering off."
    # The outcome round-trips through JSON, as it is stored with a grade.
    assert CheckOutcome.model_validate_json(outcome.model_dump_json()) == outcome


def test_a_failed_outcome_names_its_failed_conditions_in_the_verdict_line(measured):
    from rubric import CaseResult
    from rubric.check import verdict_line

    lost = CaseResult(spec=get_case("friction-table-0.30"), status="failed", error="case process failed (exit 1): boom")
    report = evaluate(_check_results(measured) | {"friction-table-0.30": lost}, outputs=OUTPUTS_OK)
    outcome = report.outcome()
    failed = [c.title for c in outcome.conditions if not c.passed]
    assert not outcome.passed and failed
    assert outcome.verdict_line == verdict_line(False, failed)
    assert outcome.verdict_line.startswith("L03 CHECK: FAILED \u2014 ") and failed[0] in outcome.verdict_line
    with pytest.raises(KeyError):
        report.outcome(notes={"no-such-condition": "x"})


def test_lane_evidence_names_each_lanes_tilt(measured):
    report = evaluate(_check_results(measured), outputs=OUTPUTS_OK)
    evidence = next(c.evidence for c in report.conditions if c.id == "friction_baseline")
    for lane in measured["friction-baseline"].metrics.lanes.values():
        assert f"{lane.case} / {lane.lane}:" in evidence and f"max tilt {lane.max_tilt_deg:.1f} deg" in evidence
