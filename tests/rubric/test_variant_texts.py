"""What a student reads about their own variant: questions, labels and the parameter summary name the variant's numbers
in English and Chinese, and reproduce the lesson's texts exactly at the lesson's own parameters. Also the lab check
under a variant: its timing table and duration are the variant's."""

from __future__ import annotations

import re

import pytest

from rubric import load_rubric
from rubric.cases import CHECK_CASES
from rubric.check import OutputLocation, evaluate
from rubric.variants import PARAMETERS, variant_cases
from rubric.variants import texts
from rubric.variants.texts import (
    CONFIG_TEMPLATES,
    DURATION_CONDITION,
    LABEL_TEMPLATES,
    QUESTION_TEMPLATES,
    SUMMARY,
    answer_label,
    config_description,
    item_question,
    parameter_rows,
    parameter_summary,
    placeholders,
    questions,
    translated,
)
from tests.rubric.synthetic_runs import synthetic_runs
from tests.rubric.test_variant_scoring import VARIANT

RUBRIC = load_rubric("L03", "2")
TEMPLATES = [("question_templates", t) for t in QUESTION_TEMPLATES.values()] + \
            [("config_templates", t) for t in CONFIG_TEMPLATES.values()] + \
            [("label_templates", t) for t in LABEL_TEMPLATES.values()] + \
            [("condition_templates", DURATION_CONDITION), ("variant_summary", SUMMARY)]


def test_each_template_renders_the_rubrics_own_text_at_the_lessons_parameters():
    shipped = texts.text_values(None)
    for item_id, template in QUESTION_TEMPLATES.items():
        assert template.format(**shipped) == RUBRIC.item(item_id).question
        # Chinese: the template's translation renders the translation the lesson already ships for that question.
        assert translated("question_templates", template, "zh").format(**shipped) == \
            translated("questions", RUBRIC.item(item_id).question, "zh")
    assert CONFIG_TEMPLATES["extension"].format(**shipped) == RUBRIC.configs["extension"].description
    assert translated("config_templates", CONFIG_TEMPLATES["extension"], "zh").format(**shipped) == \
        translated("configs", RUBRIC.configs["extension"].description, "zh")
    for label, template in LABEL_TEMPLATES.items():
        assert template.format(**shipped) == label
        assert translated("label_templates", template, "zh").format(**shipped) == translated("labels", label, "zh")
    assert translated("condition_templates", DURATION_CONDITION, "zh").format(**shipped) == translated(
        "conditions", DURATION_CONDITION.format(**shipped), "zh")


@pytest.mark.parametrize("section, template", TEMPLATES)
def test_every_template_has_its_chinese_with_the_same_placeholders(section, template):
    zh = translated(section, template, "zh")
    assert zh is not None, f"{section}: no Chinese for {template!r}"
    assert placeholders(zh) == placeholders(template) <= set(texts.text_values(None))
    assert re.search(r"[\u4e00-\u9fff]", zh)


def test_without_a_variant_every_text_is_the_lessons():
    for item in RUBRIC.items:
        assert item_question(item) == item.question
        assert item_question(item, None, "zh") == translated("questions", item.question, "zh")
    assert questions(RUBRIC) == {item.id: item.question for item in RUBRIC.items}
    assert config_description(RUBRIC, "extension") == RUBRIC.configs["extension"].description
    assert answer_label("samples 150") == "samples 150" and answer_label("samples 75", None, "zh") == "75 个采样"
    assert parameter_summary() == (
        "Your cube starts at 1.0 m (edge 0.08 m, density 500 kg/m³); the contact cases run 1.5 s at dt 0.01 s and "
        "0.02 s with 1 and 2 substeps, the extension at dt 0.01 s with 4 substeps; lane frictions 0.10 and 0.80, "
        "launched at 2.0 m/s; table 0.50, exercise table 0.30.")
    assert not any(changed for *_, changed in parameter_rows())


def test_a_variant_reads_its_own_numbers_in_english_and_chinese():
    en, zh = questions(RUBRIC, VARIANT), questions(RUBRIC, VARIANT, "zh")
    assert en["B1"] == "Which lane's effective pair value changes when table friction goes from 0.45 to 0.25?"
    assert zh["B1"] == "当桌面摩擦从 0.45 变为 0.25 时，哪条轨道的有效接触对摩擦值会改变？"
    assert en["A1"] == "Which cases have 400 outer samples, and which have 200?"
    assert en["C1"].startswith("With dt=0.01 and substeps=2,") and "over 2.0 s" in en["C1"]
    assert en["C5"].startswith("With table friction 0.45 and cube friction 0.15,")
    assert "(0.75)" in en["C6"] and en["X2"] == "What may improve with dt=0.005 and substeps=4?"
    for text in [*en.values(), *zh.values()]:
        assert "{" not in text and "0.50" not in text and "1.5 s" not in text, text
    # Items without numbers keep the lesson's text.
    assert en["A3"] == RUBRIC.item("A3").question and zh["C4"] == translated("questions", RUBRIC.item("C4").question,
                                                                              "zh")
    assert config_description(RUBRIC, "extension", VARIANT, "zh") == "第五个接触案例保持所有物理参数和 2.0 s 的时长不变"
    assert answer_label("samples 150", VARIANT) == "samples 400" and answer_label("samples 75", VARIANT, "zh") == \
        "200 个采样"
    assert answer_label("agree", VARIANT, "zh") == translated("labels", "agree", "zh")


def test_the_parameter_summary_states_the_students_own_lab():
    summary = parameter_summary(VARIANT)
    assert summary.startswith("Your cube starts at 0.95 m (edge 0.07 m, density 800 kg/m³);")
    assert "lane frictions 0.15 and 0.75, launched at 2.2 m/s; table 0.45, exercise table 0.25." in summary
    zh = parameter_summary(VARIANT, "zh")
    assert zh.startswith("你的立方体从 0.95 m 高处开始下落") and "桌面摩擦 0.45，练习中的桌面摩擦 0.25。" in zh
    assert placeholders(SUMMARY) == set(PARAMETERS)  # every parameter a variant may move is stated
    rows = {name: (value, changed) for name, _, value, changed in parameter_rows(VARIANT, "zh")}
    assert rows["cube_start_z"] == ("0.95 m", True) and rows["base_substeps"] == ("1", False)
    labels = [label for _, label, _, _ in parameter_rows(VARIANT, "zh")]
    assert all(re.search(r"[\u4e00-\u9fff]", label) for label in labels)


def test_a_locale_without_a_template_shows_english_with_the_variants_numbers_never_the_lessons():
    assert questions(RUBRIC, VARIANT, "fr")["B1"] == questions(RUBRIC, VARIANT)["B1"]
    assert parameter_summary(VARIANT, "fr") == parameter_summary(VARIANT)


def test_a_reworded_question_is_never_overwritten_by_a_stale_template():
    reworded = RUBRIC.item("B1").model_copy(update={"question": "Which pair value changes when the table gets slicker?"})
    assert item_question(reworded, VARIANT) == reworded.question


def test_the_lab_check_expects_the_variants_timing_and_duration():
    outputs = OutputLocation(passed=True, evidence="outputs in a temporary folder")
    lesson = synthetic_runs([variant_cases()[n] for n in CHECK_CASES])
    mine = synthetic_runs([VARIANT.cases()[n] for n in CHECK_CASES])
    assert evaluate(lesson, outputs=outputs, rubric=RUBRIC).passed
    report = evaluate(mine, outputs=outputs, rubric=RUBRIC, variant=VARIANT)
    assert report.passed, report.render_text()
    assert next(c for c in report.conditions if c.id == "duration").title == \
        "every contact case covers 2.0 s, so sample count changes with dt"
    # Each checked against the other's table: the timing and the duration are refused, naming the lesson table.
    for runs, variant in ((mine, None), (lesson, VARIANT)):
        failed = evaluate(runs, outputs=outputs, rubric=RUBRIC, variant=variant).failed
        assert [c.id for c in failed] == ["duration", "timing_table"]
    timing = next(c for c in evaluate(mine, outputs=outputs, rubric=RUBRIC).failed if c.id == "timing_table")
    assert "(lesson table: {'dt': 0.01, 'substeps': 1" in timing.evidence
