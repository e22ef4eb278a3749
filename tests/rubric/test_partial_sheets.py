"""An assignment's part of the sheet: exactly its answers, only the lesson's own cases for checkpoints, only its items
graded."""

from __future__ import annotations

import pytest
from pydantic import ValidationError

import rubric
from rubric.sheet import CHECKPOINT_IDS, EXERCISE_IDS
from tests.factories import reference_sheet


def part(ids, *, configs: bool) -> dict:
    sheet = reference_sheet()
    out = {"lesson": "L03", "student": "alice", "answers": {k: v for k, v in sheet["answers"].items() if k in ids}}
    return {**out, "configs": sheet["configs"]} if configs else out


def test_the_two_parts_make_the_whole_sheet():
    assert set(CHECKPOINT_IDS) | set(EXERCISE_IDS) == {i.id for i in rubric.load_rubric("L03").items}
    assert {i.id for i in rubric.load_rubric("L03").items if i.part == "checkpoint"} == set(CHECKPOINT_IDS)


def test_a_checkpoint_sheet_needs_only_the_lessons_own_cases_and_grades_only_its_items(measured):
    """The cases it lists are all its checks read: graded on those alone, the reference answers get every point."""
    from rubric.scoring import LESSON_RUNS

    sheet = rubric.parse_sheet(part(CHECKPOINT_IDS, configs=False), "checkpoints")
    specs = rubric.cases_to_run(sheet)
    assert [s.name for s in specs] == list(LESSON_RUNS)
    assert all(s == rubric.BASELINE_CASES[s.name] for s in specs)  # the lesson's cases, the same for every student
    report = rubric.grade_sheet(sheet, {s.name: measured[s.name] for s in specs})
    assert [i.id for i in report.items] == list(CHECKPOINT_IDS) and report.max_total == 8
    assert {i.id: i.verdict for i in report.items} == dict.fromkeys(CHECKPOINT_IDS, "credit")
    # Without them the measured checkpoints cannot be decided (the service never grades one that way).
    short = {i.id: i.verdict for i in rubric.grade_sheet(sheet, {}).items}
    assert short["C1"] == short["C5"] == "not_measured" and short["C2"] == "credit"


def test_an_exercise_sheet_runs_its_cases_and_grades_no_checkpoint():
    sheet = rubric.parse_sheet(part(EXERCISE_IDS, configs=True), "exercises")
    full = rubric.parse_sheet(reference_sheet())
    assert [s.name for s in rubric.cases_to_run(sheet)] == [s.name for s in rubric.cases_to_run(full)]
    assert not set(CHECKPOINT_IDS) & {i.id for i in rubric.grade_sheet(sheet, {}).items}


@pytest.mark.parametrize("items, data, where", [
    ("checkpoints", lambda: reference_sheet(), "answers.A1"),  # an answer outside the part
    ("checkpoints", lambda: part(CHECKPOINT_IDS, configs=True), "configs.table_exercise"),
    ("exercises", lambda: part(CHECKPOINT_IDS, configs=True), "answers.A1"),  # a missing answer of the part
    ("sheet", lambda: part(CHECKPOINT_IDS, configs=True), "answers.A1"),
])
def test_a_sheet_holds_exactly_its_part(items, data, where):
    with pytest.raises(ValidationError) as err:
        rubric.parse_sheet(data(), items)
    assert where in {".".join(map(str, e["loc"])) for e in err.value.errors()}
