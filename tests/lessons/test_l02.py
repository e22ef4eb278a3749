"""L02, the lesson that proves a lesson is a folder (issue 45): its sheet, scoring and lab check on real Genesis runs
(`l02_measured`: S1, S2 and the reference exercise, measured once per test run in one warm process)."""

from __future__ import annotations

import copy
from pathlib import Path

import pytest
import yaml
from pydantic import ValidationError

from rubric import cases_to_run, describe_errors, grade_sheet, load_rubric, one_factor_findings, parse_sheet
from rubric.check import OutputLocation
from rubric.lesson import lesson, lesson_of_kind
from rubric.lesson_check import check_lesson

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"
pytestmark = pytest.mark.slow


@pytest.fixture
def reference() -> dict:
    return yaml.safe_load((EXAMPLES / "l02" / "reference.yaml").read_text())


def test_l02_is_a_lesson_of_its_own_folder_found_by_entry_point():
    l02 = lesson("L02")
    assert l02.origin == "entry point L02 = lessons.l02.lesson:LESSON"
    assert l02.files == Path(__file__).resolve().parents[2] / "lessons" / "l02"
    assert lesson_of_kind("drop") is l02 and lesson_of_kind("contact").name == "L03"
    assert l02.verdict_line(True) == "L02 CHECK: PASSED" and l02.title("zh") != l02.title("en")
    assert check_lesson(l02) == []


def test_the_lesson_check_names_a_chart_title_or_part_heading_left_untranslated(tmp_path):
    """What the declaration titles itself (Lesson.part_titles, Lesson.charts) needs its Chinese text like a question."""
    import dataclasses
    import shutil

    l02 = lesson("L02")
    files = shutil.copytree(l02.files, tmp_path / "l02", ignore=shutil.ignore_patterns("*.py", "__pycache__"))
    texts = yaml.safe_load((files / "L02.zh.yaml").read_text(encoding="utf-8"))
    del texts["charts"]["The box's vertical velocity vz, every run"]
    del texts["part_titles"]["Exercise: your own timing"]
    (files / "L02.zh.yaml").write_text(yaml.safe_dump(texts, allow_unicode=True), encoding="utf-8")
    problems = check_lesson(dataclasses.replace(l02, files=files))
    assert [(p.field, p.rule) for p in problems] == [
        ("part_titles.'Exercise: your own timing'", "part hands_on's heading in L02's declaration has no zh text"),
        ("charts.\"The box's vertical velocity vz, every run\"",
         "chart drop-vz's title in L02's declaration has no zh text")], problems


def test_a_sheet_is_read_by_the_lesson_it_names_and_its_errors_name_the_item(reference):
    assert parse_sheet(reference).lesson == "L02"
    bad = copy.deepcopy(reference)
    bad["answers"]["C2"]["internal_dt"]["unit"] = "m"
    bad["answers"]["P4"]["lower"] = "S3"
    with pytest.raises(ValidationError) as info:
        parse_sheet(bad)
    errors = describe_errors(info.value)
    assert any(e.startswith("answers.C2.internal_dt.unit: Input should be 's' or 'ms'") for e in errors), errors
    assert any(e.startswith("answers.P4.lower: Input should be 'S1', 'S2' or 'same'") for e in errors), errors
    bad["lesson"] = "L09"
    with pytest.raises(ValidationError) as info:
        parse_sheet(bad)
    assert describe_errors(info.value) == ["lesson: Input should be 'L02' or 'L03' (the installed lessons)"]


def test_a_checkpoint_sheet_answers_the_checkpoints_alone(reference):
    checkpoints = {**reference, "answers": {k: reference["answers"][k] for k in ("C1", "C2", "C3")}}
    checkpoints.pop("configs")
    sheet = parse_sheet(checkpoints, "checkpoints")
    assert [spec.name for spec in cases_to_run(sheet)] == ["S1", "S2"]
    with pytest.raises(ValidationError, match="P1"):
        parse_sheet({**checkpoints, "answers": {**checkpoints["answers"], "P1": reference["answers"]["P1"]}},
                    "checkpoints")


def test_the_reference_sheet_earns_every_point_on_real_runs(reference, l02_measured):
    sheet = parse_sheet(reference)
    assert sorted(l02_measured) == ["S1", "S2", "sheet.exercise"]
    report = grade_sheet(sheet, l02_measured)
    book = load_rubric("L02")
    assert [(i.id, i.verdict) for i in report.items] == [(item.id, "credit") for item in book.items]
    assert report.total == report.max_total == book.max_total == 22 and report.complete
    assert all(backend == "cpu" for item in report.items for backend in item.backends.values())


def test_misconceptions_lose_exactly_their_items(reference, l02_measured):
    data = copy.deepcopy(reference)
    data["answers"]["C2"]["internal_dt"] = {"value": 5, "unit": "ms"}  # dt, not dt / substeps
    data["answers"]["P1"]["height"] = {"value": 0.95, "unit": "m"}  # the box's bottom, not where it has fallen to
    data["answers"]["P3"]["time"] = {"value": 0.4, "unit": "s"}  # ignoring that the box's centre sits 5 cm up
    data["answers"]["P4"]["lower"] = "same"  # "a smaller dt changes nothing in free fall"
    data["answers"]["E1"] = {"samples": 150, "internal_updates": 150}  # substeps forgotten
    report = grade_sheet(parse_sheet(data), l02_measured)
    verdicts = {i.id: i.verdict for i in report.items}
    assert {k for k, v in verdicts.items() if v != "credit"} == {"C2", "P1", "P3", "P4", "E1"}
    assert set(verdicts.values()) == {"credit", "no_credit"}
    assert report.total == 22 - (3 + 3 + 3 + 3 + 4)
    assert report.item("P4").expected == "S1" and "S1's box is -0.0" in report.item("P4").measured


def test_an_exercise_that_changes_more_than_the_timing_is_not_run_and_voids_only_its_item(reference, l02_measured):
    data = copy.deepcopy(reference)
    data["configs"]["exercise"]["duration"] = 0.8
    sheet = parse_sheet(data)
    finding = one_factor_findings(sheet, load_rubric("L02"))["exercise"]
    assert [c.field for c in finding.violations] == ["duration"]
    assert [spec.name for spec in cases_to_run(sheet)] == ["S1", "S2"]
    report = grade_sheet(sheet, {k: v for k, v in l02_measured.items() if k != "sheet.exercise"})
    assert report.item("E1").verdict == "one_factor_violation" and "duration: 0.6 -> 0.8" in report.item("E1").measured
    assert all(i.verdict == "credit" for i in report.items if i.id != "E1")


def test_a_missing_run_is_not_measured_never_credited(reference, l02_measured):
    report = grade_sheet(parse_sheet(reference), {k: v for k, v in l02_measured.items() if k != "S2"})
    assert {i.id for i in report.items if i.verdict == "not_measured"} == {"C1", "C2", "C3", "P4"}
    assert not report.complete and report.total == 3 + 2 + 3 + 4


def test_the_lab_check_passes_on_real_runs_and_fails_naming_what_is_missing(l02_measured):
    l02 = lesson("L02")
    outputs = OutputLocation(passed=True, evidence="test")
    lab = {name: l02_measured[name] for name in l02.check_cases}
    report = l02.evaluate_check(lab, outputs=outputs)
    assert report.passed, report.render_text()
    assert report.render_text().endswith("L02 CHECK: PASSED")
    assert [c.id for c in report.conditions] == ["runs", "counts", "duration", "free_fall", "touch", "outputs"]
    failed = l02.evaluate_check({"S1": lab["S1"]}, outputs=outputs).outcome()
    assert not failed.passed
    assert failed.verdict_line.startswith("L02 CHECK: FAILED \u2014 S1 and S2 were built, stepped and observed")


def test_a_course_file_of_two_lessons_names_each_item_with_its_lesson(reference, l02_measured):
    from rubric.exports import grades_csv

    l02 = grade_sheet(parse_sheet(reference), l02_measured)
    l03 = l02.model_copy(update={"lesson": "L03", "items": [l02.items[0]]})  # another lesson whose C1 is not L02's
    header, first, second = grades_csv([("alice", l02), ("alice", l03)]).splitlines()
    columns = header.split(",")
    assert columns[:3] == ["student", "lesson", "rubric_version"] and {"L02.C1", "L03.C1", "L02.E1"} <= set(columns)
    assert first.split(",")[1] == "L02" and second.split(",")[columns.index("L02.C1")] == ""
    alone = grades_csv([("alice", l02)]).splitlines()[0].split(",")
    assert "lesson" not in alone and alone[-8:] == ["C1", "C2", "C3", "P1", "P2", "P3", "P4", "E1"]
