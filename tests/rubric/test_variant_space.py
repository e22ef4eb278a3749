"""The variant space as reviewed data: the shipped file loads, every declaration carries its review, and each broken
rule is refused naming the field and the rule (as the rubric loader does)."""

from __future__ import annotations

import pytest
import yaml
from pydantic import ValidationError

from rubric import load_rubric
from rubric import rubrics
from rubric.rubrics import rubric_versions
from rubric.specs import describe_errors
from rubric.variants import (
    PARAMETERS,
    load_variant_space,
    parse_variant_space,
    variant_space_for,
    variant_space_versions,
)
from rubric.variants.expr import RuleError, evaluate_rule, parse_rule


@pytest.fixture
def data() -> dict:
    return load_variant_space("L03", "1").model_dump(mode="json")


def refused(data: dict) -> str:
    with pytest.raises(ValidationError) as info:
        parse_variant_space(data)
    return "\n".join(describe_errors(info.value))


def test_the_shipped_space_loads_for_rubric_v2_and_reviews_every_declaration():
    assert variant_space_versions("L03") == ["1", "2"]  # issue 47: v2 fitted from measurement
    space = load_variant_space("L03", "1")
    assert (space.lesson, space.version, space.grading_rubric) == ("L03", "1", "2")
    assert set(space.parameters) <= set(PARAMETERS) and space.constraints
    for name, declared in [*space.parameters.items(), *space.constraints.items()]:
        assert len(declared.rationale) >= 20 and declared.reviewer and declared.review_date, name
    # The variant file is not a rubric version: the versions, and what "latest" means, are as before.
    assert "variants" not in " ".join(rubric_versions("L03"))
    assert variant_space_for(load_rubric("L03", "2")) == load_variant_space("L03", "2")  # the latest for v2 (issue 47)
    assert variant_space_for(load_rubric("L03", "1")) is None  # no variants: grades as it always did


def test_range_values_are_exact_decimals_and_substeps_whole_numbers():
    choices = load_variant_space("L03", "1").choices()
    assert choices["cube_start_z"] == (0.9, 0.95, 1.0, 1.05, 1.1)
    assert choices["table_friction"] == (0.4, 0.45, 0.5, 0.55, 0.6)
    assert all(type(v) is int for v in choices["more_substeps"] + choices["extension_substeps"])
    assert all(type(v) is float for v in choices["cube_rho"])


@pytest.mark.parametrize("edit, message", [
    (lambda d: d["parameters"].__setitem__("drop_height", d["parameters"].pop("cube_start_z")),
     "parameters.drop_height: unknown parameter; the lesson's parameters are cube_start_z"),
    (lambda d: d["parameters"]["cube_rho"].__setitem__("range", {"min": 300, "max": 900, "step": 100}),
     "parameters.cube_rho: give exactly one of choices or range"),
    (lambda d: d["parameters"]["cube_rho"].pop("choices"),
     "parameters.cube_rho: give exactly one of choices or range"),
    (lambda d: d["parameters"]["cube_size"].__setitem__("unit", "cm"),
     "parameters.cube_size.unit: 'cm', but cube_size is measured in 'm'"),
    (lambda d: d["parameters"]["more_substeps"].__setitem__("choices", [2, 2.5]),
     "parameters.more_substeps: more_substeps takes whole numbers"),
    (lambda d: d["parameters"]["low_lane_friction"].__setitem__("choices", [0.005, 0.1]),
     "parameters.low_lane_friction: values [0.005] outside what the case schema accepts, [0.01, 5] 1"),
    (lambda d: d["parameters"]["cube_rho"].__setitem__("choices", [500.0, 500.0]),
     "parameters.cube_rho.choices: duplicate values"),
    (lambda d: d["parameters"]["table_friction"].__setitem__("range", {"min": 0.6, "max": 0.4, "step": 0.05}),
     "parameters.table_friction.range: min 0.6 is above max 0.4"),
    (lambda d: d["parameters"]["table_friction"].__setitem__("range", {"min": 0.01, "max": 5.0, "step": 0.001}),
     "parameters.table_friction: more than 200 values"),
    (lambda d: d["parameters"]["cube_size"].pop("rationale"), "parameters.cube_size.rationale: Field required"),
    (lambda d: d["parameters"]["cube_size"].pop("reviewer"), "parameters.cube_size.reviewer: Field required"),
    (lambda d: d["constraints"]["coarse_is_coarser"].__setitem__("rule", "coarse_dt > fine"),
     "constraints.coarse_is_coarser.rule: unknown name 'fine'"),
    (lambda d: d["constraints"]["coarse_is_coarser"].__setitem__("rule", "__import__('os')"),
     "constraints.coarse_is_coarser.rule: only the functions abs, min, max, close, integral may be called"),
    (lambda d: d["constraints"]["coarse_is_coarser"].__setitem__("rule", "fine_dt.real > 0"),
     "constraints.coarse_is_coarser.rule: Attribute is not allowed"),
    (lambda d: d["constraints"]["coarse_is_coarser"].__setitem__("rule", "coarse_dt >"),
     "constraints.coarse_is_coarser.rule: not an expression"),
    # A rule the lesson itself breaks was written the wrong way round.
    (lambda d: d["constraints"]["coarse_is_coarser"].__setitem__("rule", "coarse_dt < fine_dt"),
     "constraints.coarse_is_coarser: the lesson's shipped parameters break this rule (coarse_dt < fine_dt is false "
     "with coarse_dt=0.02, fine_dt=0.01)"),
    (lambda d: d.__setitem__("parameters", {}), "parameters: Dictionary should have at least 1 item"),
])
def test_each_broken_rule_is_named(data, edit, message):
    edit(data)
    assert message in refused(data)


def test_a_variant_file_naming_an_unpublished_rubric_is_refused(tmp_path, monkeypatch):
    for path in rubrics.LESSONS_DIR.glob("L03-v*.yaml"):
        (tmp_path / path.name).write_text(path.read_text())
    data = load_variant_space("L03", "1").model_dump(mode="json") | {"grading_rubric": "7"}
    (tmp_path / "L03-lab-variants-v1.yaml").write_text(yaml.safe_dump(data))
    monkeypatch.setattr(rubrics, "lesson_folder", lambda lesson: tmp_path)
    with pytest.raises(ValueError, match="grading_rubric '7' is not a published rubric version of L03"):
        load_variant_space("L03")
    with pytest.raises(LookupError, match="no variant space version '2'"):
        load_variant_space("L03", "2")


def test_violations_name_the_constraint_and_the_values_it_read():
    space = load_variant_space("L03", "1")
    assert space.violations({}) == []  # the lesson's own parameters satisfy every constraint
    broken = space.violations({"low_lane_friction": 0.6, "fine_dt": 0.005})
    assert broken == [
        "n1_n4_share_substep_dt: close(fine_dt / base_substeps, coarse_dt / more_substeps) is false with "
        "fine_dt=0.005, base_substeps=1, coarse_dt=0.02, more_substeps=2",
        "lanes_straddle_table: low_lane_friction < table_friction < high_lane_friction is false with "
        "low_lane_friction=0.6, table_friction=0.5, high_lane_friction=0.8",
        "exercise_lowers_table: low_lane_friction < exercise_table_friction < table_friction is false with "
        "low_lane_friction=0.6, exercise_table_friction=0.3, table_friction=0.5",
    ]


def test_the_rule_language_evaluates_without_eval():
    names = {"a", "b"}
    assert evaluate_rule(parse_rule("a < b <= 2 * a and not a == b", names), {"a": 1.0, "b": 2.0})
    assert evaluate_rule(parse_rule("integral(1.5 / a) and close(a * 3, 0.03)", names), {"a": 0.01, "b": 0})
    assert not evaluate_rule(parse_rule("integral(1.5 / a)", names), {"a": 0.04, "b": 0})
    assert not evaluate_rule(parse_rule("b / a > 1", names), {"a": 0.0, "b": 1.0})  # division by zero fails the rule
    for text in ("[a for a in b]", "a if b else 1", "'text' == a", "a @ b", "(lambda: 1)()", "a[0]", "True"):
        with pytest.raises(RuleError):
            parse_rule(text, names)



def test_no_glob_for_rubric_versions_picks_up_the_variant_file():
    assert not [p.name for p in rubrics.LESSONS_DIR.glob("L03-v*.yaml") if "variant" in p.name]


def test_version_2_is_version_1_fitted_to_where_the_lab_check_holds_published_with_a_review_of_each_change():
    """Issue 47: v2 is what measurement left of v1 (docs/variants.md: tools.variant_space's report). Every variant it
    draws runs N1 at the lesson's internal step of 0.01 s (v1's measured drops all ran it finer), and density no longer
    varies (it changed nothing graded), nor do the cube and the drop height (the draft that varied them kept 8 of 18);
    every change from v1 carries a fresh review, so governance publishes it."""
    from rubric import publish_variant_space
    from rubric.governance import variant_space_changes
    from rubric.variants import draw_pool

    v1, v2 = load_variant_space("L03", "1"), load_variant_space("L03", "2")
    assert publish_variant_space(v2, [v1], {"1"}) is v2
    assert {"cube_rho", "fine_dt", "base_substeps", "cube_size", "cube_start_z"} & set(v2.parameters) == set()
    assert v2.constraints["n1_internal_step_as_lesson"].rule == "close(fine_dt / base_substeps, 0.01)"
    assert "constraints.n1_internal_step_as_lesson: absent -> {'rule': 'close(fine_dt / base_substeps, 0.01)'}" in \
        variant_space_changes(v1, v2)
    shipped = v2.fill({})  # every parameter v2 does not vary at its shipped value
    for seed in (1, 2, 3):
        for v in draw_pool(v2, seed, 16).variants:
            p = v.parameters
            assert abs(p["fine_dt"] / p["base_substeps"] - 0.01) < 1e-12, v.id
            # the contact scene is the lesson's: cube and drop height (their drops, docs/variants.md) and density
            assert all(p[n] == shipped[n] for n in ("cube_rho", "cube_size", "cube_start_z")), v.id
            assert abs(p["coarse_dt"] / p["more_substeps"] - 0.01) < 1e-12, v.id  # N4 shares N1's step
    # The constraint is what screens a finer N1 step, should a later version list fine_dt again.
    assert v2.violations({"fine_dt": 0.005}) and v1.violations({"fine_dt": 0.005, "coarse_dt": 0.01}) == []
