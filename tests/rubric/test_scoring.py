"""Grading real sheets against real measurements: full marks, misconceptions, one-factor findings, failed cases."""

from __future__ import annotations

import copy
from pathlib import Path

import numpy as np
import pytest

import dataclasses

from rubric import COLOR_SWAP, ArchivedRubric, CaseResult, cases_to_run, grade_sheet, load_rubric, parse_sheet
from rubric.rubrics import Tolerance
from rubric.scoring import SCORING_RULES
from tests.factories import reference_sheet, two_lanes
from worker import run_cases

REFERENCE = reference_sheet()

# Each misconception named in the issue, as the answers a student holding it would give.
MISCONCEPTIONS = {
    "equal substep_dt means equal array length": {("A4", "same_length"): True},
    "lowering table friction changes both lanes": {
        ("B1", "lanes"): ["low", "high"], ("B3", "lane"): "neither", ("H3", "high"): "farther",
    },
    "more substeps always fix every contact problem": {("X3", "every_diagnostic_improves"): True},
    "the blue cube is more slippery": {("C7", "color_effect"): "blue_slides_farther", ("B2", "lane"): "high"},
}


def sheet_data(changes: dict | None = None, student: str = "reference", configs: dict | None = None) -> dict:
    data = copy.deepcopy(REFERENCE)
    data["student"] = student
    for (item, key), value in (changes or {}).items():
        data["answers"][item][key] = value
    data["configs"].update(configs or {})
    return data


def table_exercise(friction: float, *, swap_colors: bool = False) -> dict:
    """A table-exercise config (one factor: table friction), optionally with the lanes' Surface colours swapped."""
    config = {"kind": "friction", "name": f"table-{friction:.2f}",
              "table": {"size": [2.0, 0.6, 0.05], "pos": [0.8, 0.0, 0.7], "friction": friction}}
    if swap_colors:
        config["lanes"] = two_lanes(swap_colors=True)
    return {"table_exercise": config}


# Students whose table exercise is another valid one-factor config: grading must follow their own measurement.
SHEETS = {
    "reference": {},
    "table-0.20": table_exercise(0.20),
    # A value the lesson never used: the low lane's pair value rises from 0.50 to 0.70.
    "table-0.70": table_exercise(0.70),
    # The lesson's 0.30 with the lane colours swapped: a visual change only, so still one factor.
    "swapped-colors": table_exercise(0.30, swap_colors=True),
}


@pytest.fixture(scope="session")
def graded_runs(measured, tmp_path_factory) -> dict[str, dict[str, CaseResult]]:
    """Per sheet: the session's baseline measurements plus the sheet's own configs, really run (one warm process)."""
    own = {key: [spec for spec in cases_to_run(parse_sheet(sheet_data(student=key, configs=configs)))
                 if spec.name not in measured] for key, configs in SHEETS.items()}
    out = tmp_path_factory.mktemp("sheets")
    renamed = {(key, spec.name): spec.model_copy(update={"name": f"{key}.{spec.name}"})
               for key, specs in own.items() for spec in specs}
    results = run_cases(renamed.values(), out, mode="warm")
    failed = {name: r.error for name, r in results.items() if not r.ok}
    assert not failed, f"student configs failed on real Genesis: {failed}"
    # Back under the names grading looks for, per sheet.
    return {key: {**measured, **{name: results[f"{key}.{name}"] for (k, name) in renamed if k == key}}
            for key in SHEETS}


def lost(report) -> set[str]:
    return {i.id for i in report.items if i.score < i.max_score}


def test_every_rubric_check_is_implemented():
    assert {item.check for item in load_rubric("L03").items} <= set(SCORING_RULES)


def test_cases_to_run_lists_baselines_and_the_sheets_configs_once():
    names = [spec.name for spec in cases_to_run(parse_sheet(sheet_data()))]
    assert len(names) == len(set(names))
    # friction-table-0.30 is not read by any item: it is there so the lab check can be evaluated on every submission.
    assert {"N1", "N2", "N3", "N4", "friction-baseline", "friction-table-0.30", COLOR_SWAP, "sheet.table_exercise",
            "sheet.extension"} == set(names)


def test_reference_sheet_gets_full_marks(graded_runs):
    rubric = load_rubric("L03")
    report = grade_sheet(parse_sheet(sheet_data()), graded_runs["reference"], rubric)
    assert [i.verdict for i in report.items] == ["credit"] * len(rubric.items), [
        (i.id, i.feedback) for i in report.items if i.verdict != "credit"]
    assert report.total == report.max_total == rubric.max_total
    assert report.complete and report.rubric_version == rubric.version and report.rubric_hash == rubric.content_hash


@pytest.mark.parametrize("misconception", list(MISCONCEPTIONS))
def test_a_misconception_loses_exactly_its_items(graded_runs, misconception):
    changes = MISCONCEPTIONS[misconception]
    report = grade_sheet(parse_sheet(sheet_data(changes)), graded_runs["reference"])
    expected = {item for item, _ in changes}
    assert lost(report) == expected
    for item_id in expected:
        item = report.item(item_id)
        assert item.verdict == "no_credit" and item.score == 0
        assert "Evidence:" in item.feedback and "Verdict: no credit" in item.feedback


def test_misconception_feedback_names_the_measured_evidence(graded_runs, measured):
    every = {k: v for changes in MISCONCEPTIONS.values() for k, v in changes.items()}
    report = grade_sheet(parse_sheet(sheet_data(every)), graded_runs["reference"])
    assert lost(report) == {item for item, _ in every}
    base = measured["friction-baseline"].metrics
    low, high = base.lane("low"), base.lane("high")
    n1, n4 = len(measured["N1"].arrays["t"]), len(measured["N4"].arrays["t"])
    assert f"measured array lengths N1 {n1}, N4 {n4}" in report.item("A4").feedback
    assert "re-run with the lane colours swapped" in report.item("C7").feedback
    assert f"friction-baseline on cpu, {COLOR_SWAP} on cpu" in report.item("C7").feedback
    assert f"high {high.stop.distance:.4f} m" in report.item("B2").feedback
    assert f"low {low.stop.distance:.4f} m" in report.item("B2").feedback
    modified = graded_runs["reference"]["sheet.table_exercise"]
    high_after = modified.metrics.lane("high").stop.distance
    assert f"high: {high.stop.distance:.4f} -> {high_after:.4f} m" in report.item("H3").feedback
    assert "high_lane_unchanged = 0.01 m" in report.item("H3").feedback
    assert "on cpu" in report.item("H3").feedback
    assert "geometric-separation samples" in report.item("X3").feedback
    assert report.item("X3").evidence["N2_separation_samples"] > report.item("X3").evidence["N1_separation_samples"]


def test_grading_follows_the_students_own_measurement(graded_runs):
    data = sheet_data(student="t020", configs=table_exercise(0.20))
    data["answers"]["H1"]["modified"]["low"] = 0.2
    report = grade_sheet(parse_sheet(data), graded_runs["table-0.20"])
    h2 = report.item("H2")
    # The reference sheet's reported 0.30 stop distances do not fit the 0.20 run: only H4 is lost.
    assert lost(report) == {"H4"}, [(i.id, i.feedback) for i in report.items if i.id in lost(report)]
    assert h2.verdict == "credit" and h2.evidence["low_modified_m"] > h2.evidence["low_baseline_m"]
    at_030 = grade_sheet(parse_sheet(sheet_data()), graded_runs["reference"]).item("H2")
    assert h2.evidence["low_modified_m"] != at_030.evidence["low_modified_m"]
    assert report.item("H1").evidence["modified_low"] == pytest.approx(0.2)


def test_a_config_the_lesson_never_used_is_graded_on_its_own_run(graded_runs):
    """Table friction 0.70: the low lane's pair value rises, so it stops shorter; the high lane's stays 0.80."""
    runs = graded_runs["table-0.70"]
    modified = runs["sheet.table_exercise"].metrics
    base = runs["friction-baseline"].metrics
    # Predictions a student who reasoned correctly about 0.70 would write, before the run.
    data = sheet_data({("B1", "lanes"): ["low"], ("H2", "low"): "shorter", ("H3", "high"): "unchanged"},
                      student="t070", configs=table_exercise(0.70))
    data["answers"]["H1"]["modified"] = {"low": 0.7, "high": 0.8}
    report = grade_sheet(parse_sheet(data), runs)
    # Only the stop distances the sheet copied from the 0.30 lesson run no longer fit.
    assert lost(report) == {"H4"}, [(i.id, i.feedback) for i in report.items if i.id in lost(report)]
    h2 = report.item("H2")
    assert modified.lane("low").stop.distance < base.lane("low").stop.distance
    assert "sheet.table_exercise on cpu" in h2.feedback and h2.evidence["low_modified_m"] == \
        modified.lane("low").stop.distance
    assert report.item("H1").evidence["modified_low"] == pytest.approx(0.7)
    assert report.item("C6").verdict == "credit" and "sheet.table_exercise/low (0.7, 0.1) -> engine 0.7" in \
        report.item("C6").feedback


def test_swapped_lane_colours_in_the_hands_on_config_are_one_factor_and_graded_on_that_run(graded_runs):
    runs = graded_runs["swapped-colors"]
    sheet = parse_sheet(sheet_data(student="swapped", configs=table_exercise(0.30, swap_colors=True)))
    assert "sheet.table_exercise" in [spec.name for spec in cases_to_run(sheet)]
    report = grade_sheet(sheet, runs)
    assert report.total == report.max_total, [(i.id, i.feedback) for i in report.items if i.id in lost(report)]
    assert "visual only, not a physical input: lanes.0.color" in report.item("H5").feedback
    own = runs["sheet.table_exercise"]
    assert [lane.color for lane in own.spec.lanes] == [(0.1, 0.3, 1.0), (1.0, 0.5, 0.0)]
    for item_id in ("H2", "H3", "H4"):
        assert "sheet.table_exercise on cpu" in report.item(item_id).feedback
    assert report.item("H2").evidence["low_modified_m"] == own.metrics.lane("low").stop.distance


TWO_FACTOR = {
    # The example: a changed cube density in the hands-on config.
    "cube density": ({"cube_rho": 800.0}, "cube_rho: 500.0 -> 800.0"),
    "a lane's friction": ({"lanes": two_lanes(low_friction=0.2)}, "lanes.0.friction: 0.1 -> 0.2"),
}


@pytest.mark.parametrize("fault", list(TWO_FACTOR))
def test_a_config_fault_voids_only_the_items_that_compare_its_run(graded_runs, fault):
    extra, described = TWO_FACTOR[fault]
    config = copy.deepcopy(REFERENCE["configs"]["table_exercise"]) | extra
    sheet = parse_sheet(sheet_data(configs={"table_exercise": config}))
    assert "sheet.table_exercise" not in [spec.name for spec in cases_to_run(sheet)]
    results = {k: v for k, v in graded_runs["reference"].items() if k != "sheet.table_exercise"}
    report = grade_sheet(sheet, results)
    # The items whose checks compare the table-exercise run with the baseline; nothing else.
    voided = {"B1", "B3", "H1", "H2", "H3", "H4"}
    assert {i.id for i in report.items if i.verdict == "one_factor_violation"} == voided
    for item_id in voided:
        assert "too many inputs changed at once" in report.item(item_id).feedback
        assert described in report.item(item_id).feedback
    # H5 asks whether only table friction changed: the config itself says no, so the reference's "true" is wrong.
    assert lost(report) == voided | {"H5"}
    assert report.item("H5").verdict == "no_credit" and described in report.item("H5").feedback
    # The pair rule is read from the runs that did happen; it keeps its score.
    assert report.item("C6").verdict == "credit"
    assert any("too many inputs changed at once" in finding for finding in report.config_findings)


@pytest.mark.parametrize("status", ["failed", "invalid", "timeout"])
def test_a_failed_case_gives_visible_not_measured_items(graded_runs, status):
    results = dict(graded_runs["reference"])
    spec = results["friction-baseline"].spec
    results["friction-baseline"] = CaseResult(spec=spec, status=status, error="case process failed (exit 1): boom")
    report = grade_sheet(parse_sheet(sheet_data()), results)
    not_measured = {i.id for i in report.items if i.verdict == "not_measured"}
    # Every item that reads the baseline friction run, including the colour and pair-friction items.
    assert not_measured == {"B1", "B2", "B3", "B4", "C5", "C6", "C7", "H1", "H2", "H3", "H4"}
    for item_id in not_measured:
        item = report.item(item_id)
        assert item.score == 0 and item.max_score == item.points
        assert f"friction-baseline (friction-baseline) {status}" in item.feedback and "boom" in item.feedback
    assert not report.complete and report.total == report.max_total - sum(report.item(i).points for i in not_measured)


def test_missing_results_are_not_measured_not_a_crash():
    report = grade_sheet(parse_sheet(sheet_data()), {})
    measured_items = {i.id for i in load_rubric("L03").items if i.kind == "measured"}
    assert {i.id for i in report.items if i.verdict == "not_measured"} == measured_items
    assert all(i.score == 0 for i in report.items if i.verdict == "not_measured")


def test_a_difference_inside_tolerance_is_inconclusive_and_not_counted(graded_runs, measured):
    results = dict(graded_runs["reference"])
    ext = results["sheet.extension"]
    # The extension's spec with N1's trajectory: a proxy difference of exactly zero.
    results["sheet.extension"] = CaseResult(spec=ext.spec, status="ok", arrays=measured["N1"].arrays,
                                            provenance=ext.provenance, metrics=measured["N1"].metrics)
    report = grade_sheet(parse_sheet(sheet_data()), results)
    x2 = report.item("X2")
    assert x2.verdict == "inconclusive" and x2.score == 0 and x2.max_score == 0
    assert "inside the reviewed tolerance" in x2.feedback and "neither credited nor penalized" in x2.feedback
    assert report.max_total == load_rubric("L03").max_total - x2.points
    assert report.total == report.max_total


def test_the_rubric_tolerance_decides_what_is_resolvable(graded_runs):
    rubric = load_rubric("L03")
    record = rubric.tolerances["proxy_resolution"].model_dump()
    # Larger than every measured proxy difference: no direction can be resolved any more.
    widened = rubric.model_copy(update={"tolerances": {**rubric.tolerances,
                                                       "proxy_resolution": Tolerance(**{**record, "value": 1.0})}})
    report = grade_sheet(parse_sheet(sheet_data()), graded_runs["reference"], widened)
    assert report.item("A2").verdict == "inconclusive" and report.item("X2").verdict == "inconclusive"
    assert report.item("A2").tolerances == {"proxy_resolution": "1 m"}


def test_rubric_v1_stays_readable_but_is_archived_for_grading(graded_runs):
    v1 = load_rubric("L03", "1")
    assert v1.version == "1" and v1.max_total == 30
    with pytest.raises(ArchivedRubric, match="v1 is archived"):
        grade_sheet(parse_sheet(sheet_data()), graded_runs["reference"], v1)


def test_a_check_may_read_only_the_tolerances_its_item_declares(graded_runs):
    rubric = load_rubric("L03")
    items = [i.model_copy(update={"tolerances": []}) if i.id == "A2" else i for i in rubric.items]
    with pytest.raises(KeyError, match="item A2 reads tolerance 'proxy_resolution'"):
        grade_sheet(parse_sheet(sheet_data()), graded_runs["reference"], rubric.model_copy(update={"items": items}))


def test_every_tolerance_is_read_by_an_item_or_the_lab_check():
    import rubric.check

    rubric_ = load_rubric("L03")
    declared = {name for item in rubric_.items for name in item.tolerances}
    lab = {name for name in rubric_.tolerances if f'"{name}"' in Path(rubric.check.__file__).read_text()}
    assert set(rubric_.tolerances) == declared | lab


def test_wrong_direction_is_no_credit_with_both_pairs_shown(graded_runs, measured):
    report = grade_sheet(parse_sheet(sheet_data({("A2", "direction"): "increase"})), graded_runs["reference"])
    a2 = report.item("A2")
    assert a2.verdict == "no_credit"
    assert a2.evidence["N2_proxy_m"] == pytest.approx(float(np.max(
        measured["N2"].spec.expected_center_z - measured["N2"].arrays["z"])))


# --- measured items follow their measurement ------------------------------------------------------------------
# Each case below changes one measurement (as another engine or backend might have produced it) and names the
# items of the reference sheet that must change verdict. A measured item that kept its verdict whatever the run
# said would be a constant in disguise.


def _with_pairs(result: CaseResult, pairs: dict[str, float]) -> CaseResult:
    lanes = {name: m.model_copy(update={"pair_friction": pairs[name], "pair_friction_values": [pairs[name]]})
             for name, m in result.metrics.lanes.items()}
    return dataclasses.replace(result, metrics=result.metrics.model_copy(update={"lanes": lanes}))


def _with_provenance(result: CaseResult, **update) -> CaseResult:
    return dataclasses.replace(result, provenance=result.provenance.model_copy(update=update))


def _min_rule_engine(runs):
    return {"friction-baseline": _with_pairs(runs["friction-baseline"], {"low": 0.1, "high": 0.5}),
            COLOR_SWAP: _with_pairs(runs[COLOR_SWAP], {"low": 0.1, "high": 0.5}),
            "sheet.table_exercise": _with_pairs(runs["sheet.table_exercise"], {"low": 0.1, "high": 0.3})}


def _colour_changed_the_physics(runs):
    # A "colour-swapped" twin whose cubes in fact slid like the 0.30 table: the low (now blue) lane went farther.
    return {COLOR_SWAP: dataclasses.replace(runs["sheet.table_exercise"], spec=runs[COLOR_SWAP].spec)}


def test_runs_recorded_under_another_genesis_version_are_never_graded(graded_runs):
    """Since the provenance guards (rubric/guards.py): not one verdict is drawn from them, H6 included, and each
    item says why (it used to be H6 alone that noticed)."""
    runs = graded_runs["reference"]
    other = {name: _with_provenance(r, versions={**r.provenance.versions, "genesis": "1.3.4"})
             for name, r in runs.items()}
    report = grade_sheet(parse_sheet(sheet_data()), other)
    measured = [i for i in report.items if i.kind == "measured"]
    assert measured and all(i.verdict == "not_measured" for i in measured), [(i.id, i.verdict) for i in measured]
    assert all("Genesis 1.3.4" in i.feedback and "pins Genesis 1.3.3" in i.feedback for i in measured), \
        [(i.id, i.feedback) for i in measured if "pins Genesis" not in i.feedback]
    assert report.item("H6").verdict == "not_measured"


def _n4_ran_other_substeps(runs):
    d = runs["N4"].provenance.discretization.model_copy(update={"substeps": 4, "substep_dt": 0.005,
                                                                "internal_updates": 300})
    return {"N4": _with_provenance(runs["N4"], discretization=d)}


def _n4_recorded_150_samples(runs):
    n1 = runs["N1"]
    return {"N4": dataclasses.replace(runs["N4"], arrays=n1.arrays, metrics=n1.metrics)}


MEASUREMENT_CHANGES = {
    "an engine that used the min pair rule": (_min_rule_engine, {"B1", "C5", "C6", "H1"}),
    "a colour swap that changed the physics": (_colour_changed_the_physics, {"B4", "C7"}),
    "an engine that ran N4 with other substeps": (_n4_ran_other_substeps, {"C1"}),
    "an N4 record with 150 samples": (_n4_recorded_150_samples, {"A1", "A4"}),
}


@pytest.mark.parametrize("change", list(MEASUREMENT_CHANGES))
def test_measured_items_change_verdict_when_the_measurement_does(graded_runs, change):
    doctor, flipped = MEASUREMENT_CHANGES[change]
    runs = graded_runs["reference"]
    report = grade_sheet(parse_sheet(sheet_data()), {**runs, **doctor(runs)})
    assert lost(report) == flipped, [(i.id, i.feedback) for i in report.items if i.id in lost(report) ^ flipped]
    assert all(report.item(i).kind == "measured" for i in flipped)


def test_a_grade_stored_before_the_lab_check_was_recorded_still_parses(graded_runs):
    from rubric import GradeReport

    report = grade_sheet(parse_sheet(sheet_data()), graded_runs["reference"])
    assert report.check is None  # grade_sheet scores items; the worker adds the check where it graded
    stored = report.model_dump(mode="json")
    stored.pop("check")
    assert GradeReport.model_validate(stored).check is None


# --- Issue 45, item 2: the L03 grades recorded before the lesson moves behind a lesson interface --------------------

GOLDEN = Path(__file__).with_name("l03_golden.json")
# Sheets whose grades the move must keep: the reference, each misconception, every sheet of SHEETS on its own runs, a
# config that breaks the one-factor rule (two inputs of the table exercise), and a student on a variant (synthetic runs).
TWO_FACTORS = {"table_exercise": copy.deepcopy(REFERENCE["configs"]["table_exercise"]) | {"cube_rho": 800.0}}


def _golden_grade(report) -> dict:
    """What the move must keep of a grade: the total, each item's verdict and score, and the lab check's line."""
    return {"total": report.total, "max_total": report.max_total, "rubric": report.rubric_version,
            "items": {i.id: [i.verdict, i.score] for i in report.items},
            "config_findings": list(report.config_findings)}


def _content_keys(specs) -> dict[str, str]:
    """Each case's content key, as the service computes it at admission (grader.services.submissions.submit)."""
    from grader.core.content_key import content_key, key_inputs

    return {spec.name: content_key(key_inputs(spec.model_dump(mode="json", exclude_computed_fields=True),
                                              backend=spec.backend, precision=spec.precision))
            for spec in specs}


def _golden_now(graded_runs) -> dict:
    from rubric.check import OutputLocation, evaluate
    from tests.rubric.test_variant_scoring import RUBRIC as VARIANT_RUBRIC, VARIANT, graded, variant_sheet

    sheets = {"reference": (sheet_data(), "reference")}
    sheets |= {f"misconception: {name}": (sheet_data(changes), "reference") for name, changes in MISCONCEPTIONS.items()}
    sheets |= {key: (sheet_data(student=key, configs=configs), key) for key, configs in SHEETS.items() if configs}
    sheets["two factors in the table exercise"] = (sheet_data(configs=TWO_FACTORS), "reference")
    out = {}
    for key, (data, runs) in sheets.items():
        sheet = parse_sheet(data)
        specs = cases_to_run(sheet)
        results = {name: r for name, r in graded_runs[runs].items() if name in {s.name for s in specs}}
        out[key] = _golden_grade(grade_sheet(sheet, results)) | {"content_keys": _content_keys(specs)}
    report, _ = graded(variant_sheet(), VARIANT)
    out[f"variant {VARIANT.id}"] = _golden_grade(report) | {
        "content_keys": _content_keys(cases_to_run(parse_sheet(variant_sheet()), VARIANT_RUBRIC, VARIANT))}
    check = evaluate({n: graded_runs["reference"][n] for n in ("N1", "N2", "N3", "N4", "friction-baseline",
                                                                "friction-table-0.30")},
                     outputs=OutputLocation(passed=True, evidence="test outputs under tmp"))
    out["lab check"] = {"line": check.verdict_line(), "conditions": {c.id: c.passed for c in check.conditions}}
    return out


def test_l03_grades_lab_check_and_content_keys_are_the_ones_recorded_before_the_lesson_moved(graded_runs):
    """Issue 45, item 2: recorded from the code before L03 moved behind the lesson interface (L03_GOLDEN_WRITE=1
    writes tests/rubric/l03_golden.json from the code as it is); every later step must give the same grades, item
    verdicts, lab check and content keys (reused measurements stay reusable). Scores are compared exactly: the
    measurements are the same real runs on the same engine versions."""
    import json
    import os

    now = json.loads(json.dumps(_golden_now(graded_runs)))
    if os.environ.get("L03_GOLDEN_WRITE") == "1":
        GOLDEN.write_text(json.dumps(now, indent=1, sort_keys=True) + "\n")
    recorded = json.loads(GOLDEN.read_text())
    assert set(now) == set(recorded)
    for key in recorded:
        assert now[key] == recorded[key], key
    assert recorded["reference"]["total"] == recorded["reference"]["max_total"]
    assert recorded["lab check"]["line"] == "L03 CHECK: PASSED"
