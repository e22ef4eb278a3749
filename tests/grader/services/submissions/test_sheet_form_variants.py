"""The sheet form's logic under a student's variant (grader.services.submissions.sheet_form, issue 34): the config
editor starts from the variant's baseline, the form's configs are one factor against it as the grader judges them,
the questions and A1's labels name the variant's numbers; with no variant, the lesson's shipped ones."""

from __future__ import annotations

import pytest
from starlette.datastructures import FormData

import rubric
from grader.services.submissions import sheet_form as form_logic
from rubric.sheet import Configs, PredictionSheet
from rubric.variants import texts

BOOK = rubric.load_rubric("L03")


@pytest.fixture(scope="module")
def variant() -> rubric.Variant:
    """v391-3: every parameter the editor shows differs from the lesson's (drop height, cube, frictions, duration)."""
    (found,) = [v for v in rubric.draw_pool(rubric.load_variant_space("L03", "1"), seed=391, k=3).variants
                if v.id == "v391-3"]
    return found


def posted(values: dict, **typed: str) -> FormData:
    """What a browser posts from a form showing `values` (form_state's), with `typed` over them."""
    pairs = [(name, value) for name, value in values.items() if isinstance(value, str)] + list(typed.items())
    return FormData([(k, v) for k, v in dict(pairs).items()])


def test_the_config_editor_starts_from_the_variants_baseline(variant):
    p = variant.parameters
    shown = form_logic.config_values(BOOK, "table_exercise", {}, variant)
    assert shown["configs.table_exercise.table.friction"] == p["table_friction"]
    assert shown["configs.table_exercise.cube_size"] == p["cube_size"]
    assert shown["configs.table_exercise.initial_speed"] == p["launch_speed"]
    assert [shown[f"configs.table_exercise.lanes.{i}.friction"] for i in (0, 1)] == [p["low_lane_friction"],
                                                                                    p["high_lane_friction"]]
    extension = form_logic.config_values(BOOK, "extension", {}, variant)
    assert extension["configs.extension.cube.pos.2"] == p["cube_start_z"]
    assert extension["configs.extension.duration"] == p["duration"]
    # each input's baseline (what "baseline 0.40" beside it and the held-field warning compare with) is the variant's
    inputs = {i.name: i for i in form_logic.config_inputs(BOOK, "table_exercise", {}, variant)}
    assert inputs["configs.table_exercise.table.friction"].default == p["table_friction"]
    # a free sheet or staff: the lesson's
    assert form_logic.config_values(BOOK, "table_exercise", {})["configs.table_exercise.table.friction"] == 0.5


def test_the_forms_exercise_config_is_one_factor_against_the_variants_baseline_as_the_grader_judges(variant):
    p = variant.parameters
    items = form_logic.item_forms(BOOK, list(texts.questions(BOOK)), variant)
    values = form_logic.form_state({}, items, BOOK, variant)
    form = posted(values, **{"configs.table_exercise.table.friction": repr(p["exercise_table_friction"]),
                             "student": "alice"})
    sheet = form_logic.sheet_from_form(form, items=items, book=BOOK, previous={}, variant=variant)
    configs = Configs.model_validate(sheet["configs"])
    assert configs.table_exercise.cube_size == p["cube_size"] and configs.extension.duration == p["duration"]
    probe = PredictionSheet.model_construct(configs=configs)
    own = rubric.one_factor_findings(probe, BOOK, variant)
    assert all(f.ok for f in own.values()), {r: f.describe() for r, f in own.items()}
    assert own["table_exercise"].describe() == (f"table_exercise vs friction-baseline: one factor (table.friction "
                                                f"{p['table_friction']} -> {p['exercise_table_friction']})")
    # the same config judged against the lesson's shipped baseline is a violation: the baseline matters
    shipped = rubric.one_factor_findings(probe, BOOK)
    assert not shipped["table_exercise"].ok
    assert {"cube_size", "cube_rho"} <= {c.field for c in shipped["table_exercise"].violations}


def test_the_forms_check_compares_with_the_variants_baseline(variant, api):
    from grader.core.db import new_session

    p = variant.parameters
    items = form_logic.item_forms(BOOK, list(texts.questions(BOOK)), variant)
    values = form_logic.form_state({}, items, BOOK, variant)
    sheet = form_logic.sheet_from_form(posted(values, student="alice"), items=items, book=BOOK, previous={},
                                       variant=variant)
    with new_session() as session:
        checks, errors = form_logic.config_checks(session=session, sheet=sheet, part="sheet", book=BOOK,
                                                  variant=variant)
        assert errors == [] and [c.violations for c in checks] == [[], []]
        # the lesson's cube typed into a variant student's config: a violation naming the variant's value
        sheet["configs"]["table_exercise"]["cube_size"] = 0.08
        checks, _ = form_logic.config_checks(session=session, sheet=sheet, part="sheet", book=BOOK, variant=variant)
        (violation,) = next(c for c in checks if c.role == "table_exercise").violations
        assert (violation.field, violation.baseline, violation.config) == ("cube_size", p["cube_size"], 0.08)
    # typed in the form, the lesson's value is left out of the config (a left-out field reads as the lesson's):
    # the same violation, as the grader will find it
    typed = form_logic.sheet_from_form(posted(values, student="alice", **{"configs.table_exercise.cube_size": "0.08"}),
                                       items=items, book=BOOK, previous={}, variant=variant)
    assert "cube_size" not in typed["configs"]["table_exercise"]
    finding = rubric.one_factor_findings(PredictionSheet.model_construct(
        configs=Configs.model_validate(typed["configs"])), BOOK, variant)["table_exercise"]
    assert [(c.field, c.baseline, c.config) for c in finding.violations] == [("cube_size", p["cube_size"], 0.08)]


@pytest.mark.parametrize("locale", ["en", "zh"])
def test_the_questions_and_a1s_labels_name_the_variants_numbers(variant, locale):
    p = variant.parameters
    (b1,) = form_logic.item_forms(BOOK, ["B1"], variant, locale)
    assert b1.localized and b1.question == texts.item_question(BOOK.item("B1"), variant, locale)
    assert f"{p['table_friction']:.2f}" in b1.question and f"{p['exercise_table_friction']:.2f}" in b1.question
    assert "0.50" not in b1.question
    fine = variant.cases()["N1"].sample_count
    assert fine != 150 and str(fine) in form_logic.answer_label("samples 150", variant, locale)
    # without a variant: the rubric's own (English) question, translated by the page
    (shipped,) = form_logic.item_forms(BOOK, ["B1"])
    assert not shipped.localized and shipped.question == BOOK.item("B1").question
    assert form_logic.answer_label("samples 150", None, "en") == "samples 150"
