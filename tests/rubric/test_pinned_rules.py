"""Pins C1's internal updates, metric-only audit drift and colours never breaking one factor, without Genesis."""

from __future__ import annotations

import numpy as np
import pytest

from rubric import CaseResult, Provenance, case_metrics, compare_cases, get_case, grade_sheet, load_audit_tolerances
from rubric import load_rubric, parse_sheet
from rubric.one_factor import one_factor_findings
from rubric.results import spec_discretization
from tests.factories import provenance, reference_sheet, two_lanes

RUBRIC = load_rubric("L03", "2")
AUDIT = load_audit_tolerances("L03")


def with_precision(spec, precision: str):
    return type(spec).model_validate({**spec.model_dump(exclude_computed_fields=True), "precision": precision})


def contact_result(spec, *, mode: str = "warm", **discretization) -> CaseResult:
    """A cube falling onto the table and resting there (every sample recorded), as a case process on CPU leaves it;
    `discretization` replaces what the engine reported in its provenance."""
    t = np.arange(1, spec.sample_count + 1) * spec.dt
    z = np.maximum(spec.cube.pos[2] - 0.5 * 9.81 * t**2, spec.expected_center_z - 0.002)
    resting = z <= spec.expected_center_z + 1e-9
    arrays = {
        "t": t, "z": z, "vz": np.gradient(z, t), "contact_count": np.where(resting, 4, 0).astype(np.int32),
        "clearance": z - spec.cube.size / 2 - spec.table.top_z, "quat": np.tile([1.0, 0.0, 0.0, 0.0], (len(t), 1)),
        "frame_initial": np.zeros((0, 0, 3), np.uint8), "frame_final": np.zeros((0, 0, 3), np.uint8),
    }
    reported = spec_discretization(spec).model_dump() | discretization
    prov = Provenance.model_validate(provenance(spec, execution_mode=mode, discretization=reported))
    return CaseResult(spec=spec, status="ok", arrays=arrays, provenance=prov, metrics=case_metrics(spec, arrays))


# --- C1: the engine's substep_dt, samples and internal updates, all three -------------------------------------------

def checkpoints(**c1) -> object:
    sheet = reference_sheet()
    answers = {k: v for k, v in sheet["answers"].items() if k.startswith("C")}
    answers["C1"] = answers["C1"] | c1
    return parse_sheet({"lesson": "L03", "student": "s", "answers": answers}, "checkpoints")


def c1(sheet, n4: CaseResult):
    return grade_sheet(sheet, {"N4": n4}, RUBRIC).item("C1")


def test_c1_credits_the_engines_reported_timing():
    n4 = contact_result(get_case("N4"))
    assert (n4.provenance.discretization.substep_dt, n4.provenance.discretization.sample_count,
            n4.provenance.discretization.internal_updates) == (0.01, 75, 150)
    item = c1(checkpoints(), n4)
    assert item.verdict == "credit" and item.score == item.points
    assert item.evidence == {"substep_dt_s": 0.01, "samples": 75, "internal_updates": 150}


@pytest.mark.parametrize("internal_updates", [75, 149, 300])
def test_c1_gets_no_credit_when_only_the_internal_updates_are_wrong(internal_updates):
    item = c1(checkpoints(internal_updates=internal_updates), contact_result(get_case("N4")))
    assert item.verdict == "no_credit" and item.score == 0, item.feedback


def test_c1_follows_the_internal_updates_the_engine_reported():
    """The lesson's answer (150) loses its credit when the engine says it made another number of updates."""
    item = c1(checkpoints(), contact_result(get_case("N4"), internal_updates=300))
    assert item.verdict == "no_credit" and item.evidence["internal_updates"] == 300


@pytest.mark.parametrize("wrong", [{"samples": 150}, {"substep_dt": {"value": 0.02, "unit": "s"}}])
def test_c1_gets_no_credit_when_samples_or_substep_dt_are_wrong(wrong):
    assert c1(checkpoints(**wrong), contact_result(get_case("N4"))).verdict == "no_credit"


# --- the audit: a metric beyond its tolerance is numeric drift even where every array agrees ------------------------

def metric_shifted(name: str, by: float) -> tuple[CaseResult, CaseResult]:
    left = contact_result(get_case("N1"))
    right = contact_result(with_precision(get_case("N1"), "64"))
    shifted = right.metrics.model_copy(update={name: getattr(right.metrics, name) + by})
    return left, CaseResult(spec=right.spec, status="ok", arrays=right.arrays, provenance=right.provenance,
                            metrics=shifted)


@pytest.mark.parametrize("metric, tolerance", [("tail_peak_to_peak", "height_abs"), ("max_tilt_deg", "tilt_abs"),
                                               ("upward_samples_after_contact", "sample_count_abs")])
def test_a_metric_beyond_its_tolerance_with_identical_arrays_is_numeric_drift(metric, tolerance):
    tol = AUDIT.tolerances[tolerance].value
    left, right = metric_shifted(metric, max(3 * tol, 1) if metric == "upward_samples_after_contact" else 3 * tol)
    c = compare_cases(left, right)
    assert all(a.bit_equal and a.within for a in c.arrays)  # every array agrees, bit for bit
    assert not any(r.changed for r in c.relations)
    assert [m.name for m in c.metrics if not m.within] == [metric]
    assert c.classification == "numeric_drift", c.summary


def test_a_metric_inside_its_tolerance_with_identical_arrays_is_within_tolerance_not_identical():
    tol = AUDIT.tolerances["height_abs"].value
    c = compare_cases(*metric_shifted("tail_peak_to_peak", tol / 2))
    assert all(m.within for m in c.metrics) and c.classification == "within_tolerance"
    same = compare_cases(*metric_shifted("tail_peak_to_peak", 0.0))
    assert same.classification == "identical"


# --- one factor: a surface colour is listed, never a violation; a physical change outside may_change is ---------------

def table_exercise_sheet(**config) -> object:
    sheet = reference_sheet()
    sheet["configs"]["table_exercise"] = sheet["configs"]["table_exercise"] | config
    return parse_sheet(sheet)


def test_a_colour_only_change_is_listed_but_no_one_factor_violation():
    from rubric import cases_to_run

    base = get_case("friction-baseline")  # its own table, the lanes' frictions and places: only the colours swapped
    sheet = table_exercise_sheet(table=base.table.model_dump(mode="json", exclude_computed_fields=True),
                                 lanes=two_lanes(swap_colors=True))
    finding = one_factor_findings(sheet, RUBRIC)["table_exercise"]
    assert [c.field for c in finding.changes] == ["lanes.0.color", "lanes.1.color"]
    assert all(c.visual for c in finding.changes)
    assert finding.violations == [] and finding.ok, finding.describe()
    assert "visual only, not a physical input: lanes.0.color" in finding.describe()
    assert "sheet.table_exercise" in [spec.name for spec in cases_to_run(sheet, RUBRIC)]  # run as a valid config


def test_a_colour_change_beside_the_allowed_factor_is_still_one_factor():
    sheet = table_exercise_sheet(lanes=two_lanes(swap_colors=True))
    finding = one_factor_findings(sheet, RUBRIC)["table_exercise"]
    assert {"table.friction", "lanes.0.color", "lanes.1.color"} <= {c.field for c in finding.changes}
    assert finding.ok and finding.violations == []


def test_a_physical_change_outside_may_change_is_a_violation():
    sheet = table_exercise_sheet(lanes=two_lanes(low_friction=0.2))
    finding = one_factor_findings(sheet, RUBRIC)["table_exercise"]
    assert [c.field for c in finding.violations] == ["lanes.0.friction"]
    assert not finding.ok and "too many inputs changed at once" in finding.describe()
