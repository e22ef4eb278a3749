"""The prediction sheet: the examples parse, bad sheets fail naming the item, the one-factor rule reports fields."""

from __future__ import annotations

import copy
import pytest
import yaml
from pydantic import ValidationError

from rubric import BASELINE_CASES, describe_errors, load_rubric, one_factor_findings, parse_sheet
from rubric import field_changes
from rubric.sheet import Answers, Configs
from tests.factories import EXAMPLES, reference_sheet, two_lanes



@pytest.fixture
def reference() -> dict:
    return reference_sheet()


def errors_of(data: dict) -> list[str]:
    with pytest.raises(ValidationError) as info:
        parse_sheet(data)
    return describe_errors(info.value)


def test_reference_sheet_parses_with_typed_answers(reference):
    sheet = parse_sheet(reference)
    assert sheet.answers.X1.substep_dt.si == pytest.approx(0.0025)  # 2.5 ms in SI
    assert sheet.answers.H4.baseline.low.si == pytest.approx(0.41)  # 41 cm
    assert sheet.answers.A1.explanation.startswith("1.5 s")
    assert set(sheet.configs.submitted()) == {"table_exercise", "extension"}


def test_every_rubric_item_is_a_sheet_question_and_back():
    assert [item.id for item in load_rubric("L03").items] == list(Answers.model_fields)


def test_template_has_every_question_and_is_not_yet_a_valid_sheet():
    template = yaml.safe_load((EXAMPLES / "template.yaml").read_text())
    assert list(template["answers"]) == list(Answers.model_fields)
    assert set(template["configs"]) == {"table_exercise", "extension"} <= set(Configs.model_fields)
    errors = errors_of(template)
    assert any(e.startswith("student:") for e in errors)
    assert any(e.startswith("answers.A3.agree:") for e in errors)


@pytest.mark.parametrize(
    ("path", "value", "expected"),
    [
        (("answers", "A3", "agree"), "yes", "answers.A3.agree: Input should be a valid boolean"),
        (("answers", "C5", "pair_friction"), "0.5", "answers.C5.pair_friction: Input should be a valid number"),
        (("answers", "A2", "direction"), "down", "answers.A2.direction: Input should be 'decrease', 'increase'"),
        (("answers", "C1", "substep_dt", "unit"), "m", "answers.C1.substep_dt.unit: Input should be 's' or 'ms'"),
        (("answers", "A1", "samples_150"), ["N1", "N1"], "answers.A1.samples_150: entries must be unique"),
        # a sheet is read by the lesson it names: one no installed lesson has is refused naming those there are
        (("lesson",), "L04", "lesson: Input should be 'L02' or 'L03' (the installed lessons)"),
        (("configs", "table_exercise", "table", "friction"), 9.0,
         "configs.table_exercise.table.friction: Input should be less than or equal to 5"),
    ],
)
def test_bad_values_are_named_by_item(reference, path, value, expected):
    data = copy.deepcopy(reference)
    target = data
    for key in path[:-1]:
        target = target[key]
    target[path[-1]] = value
    errors = errors_of(data)
    assert any(e.startswith(expected) for e in errors), errors


def test_unknown_question_id_and_unknown_field_are_errors(reference):
    data = copy.deepcopy(reference)
    data["answers"]["A9"] = {"agree": True}
    data["answers"]["B2"]["colour"] = "blue"
    errors = errors_of(data)
    assert "answers.A9: Extra inputs are not permitted" in errors
    assert "answers.B2.colour: Extra inputs are not permitted" in errors


def test_missing_answers_are_named(reference):
    data = copy.deepcopy(reference)
    del data["answers"]["H4"]
    del data["answers"]["X3"]["every_diagnostic_improves"]
    del data["configs"]["extension"]
    errors = errors_of(data)
    assert "answers.H4: Field required" in errors
    assert "answers.X3.every_diagnostic_improves: Field required" in errors
    assert "configs.extension: Field required" in errors


def test_duplicate_config_names_are_refused(reference):
    data = copy.deepcopy(reference)
    data["configs"]["N2"] = {"kind": "contact", "name": "N5", "substeps": 2}
    assert any("case names must be unique" in e for e in errors_of(data))


def test_reference_configs_change_one_declared_factor(reference):
    findings = one_factor_findings(parse_sheet(reference), load_rubric("L03"))
    assert findings["table_exercise"].ok
    assert [c.field for c in findings["table_exercise"].changes] == ["table.friction"]
    assert [c.field for c in findings["extension"].changes] == ["substeps"]


def test_two_factor_config_is_reported_field_by_field(reference):
    data = copy.deepcopy(reference)
    data["configs"]["table_exercise"]["lanes"] = two_lanes(low_friction=0.2)
    data["configs"]["table_exercise"]["initial_speed"] = 3.0
    finding = one_factor_findings(parse_sheet(data), load_rubric("L03"))["table_exercise"]
    assert not finding.ok
    assert {c.field for c in finding.violations} == {"lanes.0.friction", "initial_speed"}
    violation = {c.field: (c.baseline, c.config) for c in finding.violations}
    assert violation["lanes.0.friction"] == (0.1, 0.2)
    assert "too many inputs changed at once" in finding.describe()


def test_part_a_role_is_compared_with_the_students_own_baseline(reference):
    data = copy.deepcopy(reference)
    data["configs"]["N1"] = {"kind": "contact", "name": "my-N1", "cube": {"rho": 800.0}}
    data["configs"]["N2"] = {"kind": "contact", "name": "my-N2", "substeps": 2, "cube": {"rho": 800.0}}
    findings = one_factor_findings(parse_sheet(data), load_rubric("L03"))
    assert [c.field for c in findings["N1"].violations] == ["cube.rho"]  # against the lesson's N1
    assert findings["N2"].ok and [c.field for c in findings["N2"].changes] == ["substeps"]  # against my-N1


def test_field_changes_ignore_only_the_label_and_rendering():
    n1 = BASELINE_CASES["N1"]
    relabelled = n1.model_copy(update={"name": "other", "render": True})
    assert field_changes(n1, relabelled) == []
    recoloured = type(n1).model_validate({**n1.model_dump(exclude_computed_fields=True),
                                          "cube": {**n1.cube.model_dump(), "color": [0.0, 0.0, 1.0]}})
    assert [c.field for c in field_changes(n1, recoloured)] == ["cube.color"]
