"""Grading under a student's variant: the lesson's cases, the one-factor baselines and the numbers expected answers
name are the variant's; with no variant everything is as it was. Runs come from tests/rubric/synthetic_runs.py (no
Genesis): the relations hold by construction, so what is tested is what the rubric expects of them."""

from __future__ import annotations

import copy

import pytest

from rubric import cases_to_run, grade_sheet, load_rubric, one_factor_findings, parse_sheet
from rubric.cases import BASELINE_CASES
from rubric.one_factor import role_baseline
from rubric.scoring import LESSON_RUNS, SHEET_CASE_PREFIX
from rubric.variants import Variant, complete_parameters, load_variant_space, shipped_variant
from tests.factories import reference_sheet
from tests.rubric.synthetic_runs import synthetic_runs

RUBRIC = load_rubric("L03", "2")
# A variant of the shipped space (every value among its choices, every constraint kept; asserted below).
VARIANT = Variant(id="v7-3", space_version="1", parameters=complete_parameters({
    "cube_start_z": 0.95, "cube_size": 0.07, "cube_rho": 800.0, "duration": 2.0, "fine_dt": 0.005, "coarse_dt": 0.01,
    "base_substeps": 1, "more_substeps": 2, "extension_dt": 0.005, "extension_substeps": 4, "table_friction": 0.45,
    "exercise_table_friction": 0.25, "low_lane_friction": 0.15, "high_lane_friction": 0.75, "launch_speed": 2.2}))


def variant_sheet(student: str = "vera") -> dict:
    """The reference sheet done on VARIANT: configs derived from the variant's cases, numbers from its parameters."""
    cases = VARIANT.cases()
    data = reference_sheet() | {"student": student}
    exercise = cases["friction-baseline"].model_dump(mode="json", exclude_computed_fields=True)
    exercise |= {"name": "table-0.25", "table": exercise["table"] | {"friction": 0.25}}
    extension = cases["N1"].model_dump(mode="json", exclude_computed_fields=True) | {"name": "N5", "substeps": 4}
    data["configs"] = {"table_exercise": exercise, "extension": extension}
    answers = data["answers"]
    answers["C1"] = {"substep_dt": {"value": 5, "unit": "ms"}, "samples": 200, "internal_updates": 400}
    answers["C5"] = {"pair_friction": 0.45}
    answers["H1"] = {"baseline": {"low": 0.45, "high": 0.75}, "modified": {"low": 0.25, "high": 0.75}}
    answers["X1"] = {"substep_dt": {"value": 1.25, "unit": "ms"}, "samples": 400, "internal_updates": 1600}
    return data


def with_measured_stops(data: dict, runs: dict) -> dict:
    """H4 answered with the stops these runs measured (what a careful student reports)."""
    data = copy.deepcopy(data)
    stops = {run: {lane: {"value": round(runs[name].metrics.lane(lane).stop.distance, 4), "unit": "m"}
                   for lane in ("low", "high")}
             for run, name in (("baseline", "friction-baseline"), ("modified", SHEET_CASE_PREFIX + "table_exercise"))}
    data["answers"]["H4"] = stops
    return data


def graded(data: dict, variant: Variant | None):
    sheet = parse_sheet(data)
    runs = synthetic_runs(cases_to_run(sheet, RUBRIC, variant))
    sheet = parse_sheet(with_measured_stops(data, runs))
    return grade_sheet(sheet, runs, RUBRIC, variant), runs


def test_the_test_variant_is_one_the_shipped_space_can_draw():
    space = load_variant_space("L03", "1")
    assert space.violations(VARIANT.parameters) == []
    assert all(VARIANT.parameters[n] in values for n, values in space.choices().items())


def test_no_variant_and_the_shipped_variant_grade_alike():
    sheet = parse_sheet(reference_sheet())
    assert cases_to_run(sheet, RUBRIC) == cases_to_run(sheet, RUBRIC, shipped_variant())
    runs = synthetic_runs(cases_to_run(sheet, RUBRIC))
    plain, shipped = grade_sheet(sheet, runs, RUBRIC), grade_sheet(sheet, runs, RUBRIC, shipped_variant())
    assert plain.variant is None and shipped.variant == "shipped"
    assert plain.model_dump(exclude={"variant"}) == shipped.model_dump(exclude={"variant"})
    assert plain.item("A1").expected == "150 samples: ['N1', 'N2'], 75 samples: ['N3', 'N4']"
    assert plain.item("C5").expected == "0.5"


def test_cases_to_run_are_the_variants_lesson_cases_under_the_lessons_names():
    sheet = parse_sheet(variant_sheet())
    specs = {spec.name: spec for spec in cases_to_run(sheet, RUBRIC, VARIANT)}
    cases = VARIANT.cases()
    assert [n for n in specs if not n.startswith(SHEET_CASE_PREFIX)] == list(LESSON_RUNS)
    assert all(specs[n] == cases[n] for n in LESSON_RUNS)
    assert specs["N1"].cube.pos[2] == 0.95 and specs["friction-table-0.30"].table.friction == 0.25
    assert {SHEET_CASE_PREFIX + "table_exercise", SHEET_CASE_PREFIX + "extension"} <= set(specs)


def test_a_variant_sheet_earns_full_marks_on_its_own_runs():
    report, _ = graded(variant_sheet(), VARIANT)
    assert report.variant == "v7-3"
    wrong = [(i.id, i.verdict, i.expected, i.measured) for i in report.items if i.verdict != "credit"]
    assert wrong == [] and report.total == report.max_total == RUBRIC.max_total
    assert report.item("A1").expected == "400 samples: ['N1', 'N2'], 200 samples: ['N3', 'N4']"
    assert report.item("C5").expected == "0.45"
    assert "250 steps cover 2.5 s at dt 0.005" not in report.item("C2").measured
    assert report.item("C2").measured == "400 steps cover 2 s at dt 0.005 but 4 s at dt 0.01"


def test_the_shipped_answers_lose_the_items_whose_numbers_the_variant_moved():
    """A sheet copied from the published reference (the lesson's numbers) on a variant: every item naming a number
    the variant moved is lost; the items whose answer does not depend on the numbers are not."""
    mine = variant_sheet()
    copied = reference_sheet() | {"student": "vera", "configs": mine["configs"]}
    report, _ = graded(copied, VARIANT)
    lost = sorted(i.id for i in report.items if i.verdict == "no_credit")
    assert lost == ["C1", "C5", "H1", "X1"], [(i.id, i.verdict, i.expected) for i in report.items]


def test_one_sheet_on_two_variants_gets_two_grades():
    data = variant_sheet()
    on_own, _ = graded(data, VARIANT)
    other = Variant(id="v7-4", space_version="1", parameters=VARIANT.parameters | {
        "table_friction": 0.5, "exercise_table_friction": 0.3, "coarse_dt": 0.02, "more_substeps": 4,
        "base_substeps": 2, "fine_dt": 0.01})
    assert load_variant_space("L03", "1").violations(other.parameters) == []
    on_other, _ = graded(data, other)
    assert on_own.total == RUBRIC.max_total > on_other.total
    # The other variant's table is 0.50 and its N4 runs dt 0.02 with 4 substeps: those answers are someone else's.
    assert sorted(i.id for i in on_other.items if i.verdict != "credit") == ["C1", "C5", "H1"]
    assert on_other.item("C1").expected == "substep_dt 0.005 s, 100 samples, 400 internal updates"


def test_lesson_runs_measured_under_other_parameters_are_not_graded_as_the_variants():
    sheet = parse_sheet(variant_sheet())
    runs = synthetic_runs(cases_to_run(sheet, RUBRIC, VARIANT))
    shipped_runs = synthetic_runs(cases_to_run(parse_sheet(reference_sheet()), RUBRIC))
    mixed = runs | {"N1": shipped_runs["N1"]}
    a3 = grade_sheet(sheet, mixed, RUBRIC, VARIANT).item("A3")
    assert a3.verdict == "not_measured"
    assert "case N1 (N1) was measured with other parameters than variant v7-3" in a3.measured
    assert "cube.pos [0.35, 0.0, 0.95] expected, [0.35, 0.0, 1.0] measured" in a3.measured
    assert "duration 2.0 expected, 1.5 measured" in a3.measured
    # The backend is where it ran, not a parameter: a variant's runs measured on another backend are graded.
    assert grade_sheet(sheet, runs, RUBRIC, VARIANT).item("A3").verdict == "credit"


def test_the_one_factor_check_compares_with_the_students_variant_baseline():
    mine = parse_sheet(variant_sheet())
    ok = one_factor_findings(mine, RUBRIC, VARIANT)
    assert all(f.ok for f in ok.values()), {r: f.describe() for r, f in ok.items()}
    assert ok["table_exercise"].describe() == "table_exercise vs friction-baseline: one factor (table.friction 0.45 -> 0.25)"
    assert ok["extension"].describe() == "extension vs N1: one factor (substeps 1 -> 4)"
    # The same configs judged against the shipped lesson: everything the variant moved counts as a changed input.
    shipped = one_factor_findings(mine, RUBRIC)
    assert sorted(c.field for c in shipped["table_exercise"].violations) == [
        "cube_rho", "cube_size", "initial_speed", "lanes.0.friction", "lanes.1.friction"]
    assert sorted(c.field for c in shipped["extension"].violations) == ["cube.pos", "cube.rho", "cube.size", "duration"]
    # And the shipped reference configs on the variant: the student did not start from their own baseline.
    theirs = one_factor_findings(parse_sheet(reference_sheet()), RUBRIC, VARIANT)
    assert not theirs["table_exercise"].ok and "cube_size: 0.07 -> 0.08" in theirs["table_exercise"].describe()
    # The form's starting config for each role is the variant's.
    assert role_baseline("table_exercise", RUBRIC, VARIANT) == VARIANT.cases()["friction-baseline"]
    assert role_baseline("table_exercise", RUBRIC) is BASELINE_CASES["friction-baseline"]
    assert role_baseline("extension", RUBRIC, VARIANT).dt == 0.005


def test_a_variant_run_whose_lanes_miss_the_questions_pair_is_not_measured():
    sheet = parse_sheet(variant_sheet())
    runs = synthetic_runs(cases_to_run(sheet, RUBRIC, VARIANT))
    other = Variant(id="v7-5", space_version="1", parameters=VARIANT.parameters | {"low_lane_friction": 0.1})
    c5 = grade_sheet(sheet, runs, RUBRIC, other).item("C5")
    assert c5.verdict == "not_measured"
    assert "lanes.0.friction 0.1 expected, 0.15 measured" in c5.measured


@pytest.mark.parametrize("role", ["N2", "N4"])
def test_an_unsubmitted_role_runs_as_the_variants_case(role):
    data = variant_sheet()
    sheet = parse_sheet(data)
    spec = next(s for s in cases_to_run(sheet, RUBRIC, VARIANT) if s.name == role)
    assert spec == VARIANT.cases()[role] and sheet.spec_for(role, VARIANT.cases()) == spec


def test_a_variant_report_asks_its_own_questions_and_exports_say_which_variant():
    from rubric import grades_csv, gradescope_results

    mine, _ = graded(variant_sheet(), VARIANT)
    assert mine.item("B1").question == ("Which lane's effective pair value changes when table friction goes from "
                                        "0.45 to 0.25?")
    lesson, _ = graded(reference_sheet(), None)
    assert [i.question for i in lesson.items] == [i.question for i in RUBRIC.items]
    # Without variants the CSV is as it always was; with one, a variant column (empty for the lesson's parameters).
    plain = grades_csv([("ref", lesson)]).splitlines()[0]
    assert plain.startswith("student,rubric_version,total,max_total,complete,A1,")
    mixed = grades_csv([("vera", mine), ("ref", lesson)]).splitlines()
    assert mixed[0].startswith("student,rubric_version,variant,total,max_total,complete,A1,")
    assert mixed[1].startswith("vera,2,v7-3,30,30,true,") and mixed[2].startswith("ref,2,,")
    assert "rubric version 2 (sha256 " in gradescope_results(lesson, 1.0)["output"]
    assert " on variant v7-3: 30 / 30" in gradescope_results(mine, 1.0)["output"].splitlines()[0]
    assert gradescope_results(mine, 1.0)["tests"][5]["name"].startswith("B1: Which lane's effective pair value "
                                                                        "changes when table friction goes from 0.45")


def test_a_pool_measures_each_variants_lesson_runs_once_for_all_its_students():
    from rubric.scoring import lesson_run_specs

    assert lesson_run_specs() == [BASELINE_CASES[n] for n in LESSON_RUNS]
    specs = lesson_run_specs(VARIANT)
    assert [s.name for s in specs] == list(LESSON_RUNS) and specs == [VARIANT.cases()[n] for n in LESSON_RUNS]
    # Two students on the variant need exactly these lesson runs, whatever else their sheets hold.
    for student in ("vera", "walt"):
        needed = [s for s in cases_to_run(parse_sheet(variant_sheet(student)), RUBRIC, VARIANT)
                  if not s.name.startswith(SHEET_CASE_PREFIX)]
        assert needed == specs


def walt_on_both():
    """Walt is on v7-4 but hands in Vera's sheet (her v7-3 numbers): his sheet graded on his own variant and, for the
    evidence, on hers (the reports of v7-4 and v7-3)."""
    other = Variant(id="v7-4", space_version="1", parameters=VARIANT.parameters | {
        "table_friction": 0.5, "exercise_table_friction": 0.3, "coarse_dt": 0.02, "more_substeps": 4,
        "base_substeps": 2, "fine_dt": 0.01})
    copied = variant_sheet("walt")
    return graded(copied, other)[0], graded(copied, VARIANT)[0]


def test_answers_that_fit_another_variant_are_shown_with_the_items_and_the_variant():
    from rubric.copying import copy_evidence

    # Nothing in the evidence changes his grade.
    on_own, on_hers = walt_on_both()
    found = copy_evidence(on_own.model_copy(update={"variant": "v7-4"}), {"v7-3": on_hers, "v7-4": on_own})
    assert [(e.variant, e.items) for e in found] == [("v7-3", ["C1", "C5", "H1"])]
    assert "C5: own 0.5, v7-3 0.45" in found[0].describe()
    # An honest sheet fits its own variant: no evidence.
    honest, _ = graded(variant_sheet(), VARIANT)
    assert copy_evidence(honest, {"v7-4": on_own}) == []


def test_copying_between_variants_that_share_most_answers_is_counted_over_the_items_where_they_differ():
    """Issue 47: two variants may expect alike on all but one item; a sheet fitting the other one there is all the
    evidence there can be, so it is shown (saying over how many items), and a pair nothing tells apart is named."""
    from rubric.copying import copy_evidence, differing_items, indistinct_variants

    on_own, on_hers = walt_on_both()
    own = on_own.model_copy(update={"variant": "v7-4"})
    # Keep every item both expect alike and one they differ on (C5): the two variants share most answers.
    differ = set(differing_items(own, on_hers))
    assert "C5" in differ and len(differ) >= 2
    keep = [i for i in own.items if i.id not in differ or i.id == "C5"]
    near_own = own.model_copy(update={"items": keep})
    near_hers = on_hers.model_copy(update={"items": [i for i in on_hers.items if i.id in {k.id for k in keep}]})
    assert differing_items(near_own, near_hers) == ["C5"]
    (found,) = copy_evidence(near_own, {"v7-3": near_hers})
    assert (found.variant, found.items, found.differing) == ("v7-3", ["C5"], 1)
    assert "on 1 items of the 1 where the two variants differ" in found.describe()
    # With the full reports, the rule of two items or more still holds and the count is given.
    (full,) = copy_evidence(own, {"v7-3": on_hers})
    assert full.items == ["C1", "C5", "H1"] and full.differing == len(differ)
    # A variant expecting alike on every measured item cannot be told apart: named, never shown as no evidence.
    alike = near_own.model_copy(update={"variant": "v7-9"})
    assert indistinct_variants(near_own, {"v7-9": alike, "v7-3": near_hers}) == ["v7-9"]
    assert copy_evidence(near_own, {"v7-9": alike}) == []
