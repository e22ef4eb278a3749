"""What a student reads about their own variant, in English and Chinese: the question texts with their numbers, the
form's labels that name numbers, and a summary of their parameters.

English templates live here, keyed by item id (or label, or role); the Chinese ones beside the lesson's other Chinese
text in rubric/lessons/L03.zh.yaml, keyed by the English template exactly as that file keys every text. A template is
used only while it reproduces the rubric's own wording at the shipped parameters, so a reworded question in a later
rubric version shows its own text (with the lesson's numbers) rather than a stale template's. With no variant, every
function returns the rubric's text or the lesson's numbers unchanged.
"""

from __future__ import annotations

import functools
import string
from collections.abc import Mapping

import yaml

from .. import rubrics
from ..rubrics import Item, Rubric
from .apply import complete_parameters, variant_cases
from .draw import Variant
from .parameters import PARAMETERS, shipped_parameters

Locale = str  # "en" (the rubric's own language) or "zh"

QUESTION_TEMPLATES = {
    "A1": "Which cases have {samples_fine} outer samples, and which have {samples_coarse}?",
    "B1": "Which lane's effective pair value changes when table friction goes from {table_friction} to "
          "{exercise_table_friction}?",
    "C1": "With dt={coarse_dt} and substeps={more_substeps}, what are substep_dt, the number of outer samples over "
          "{duration} s, and the number of internal updates?",
    "C5": "With table friction {table_friction} and cube friction {low_lane_friction}, what pair value does Genesis "
          "1.3.3 use in this experiment?",
    "C6": "Why does lowering the table to {exercise_table_friction} affect the low-friction lane but not the "
          "high-friction cube ({high_lane_friction})? (the pair rule)",
    "H2": "Expected direction of the low-friction lane's stopping-distance change when table friction drops to "
          "{exercise_table_friction}",
    "H3": "Expected direction of the high-friction lane's stopping-distance change when table friction drops to "
          "{exercise_table_friction}",
    "X1": "Fifth case dt={extension_dt}, substeps={extension_substeps}: substep_dt, outer samples over {duration} s "
          "and internal updates (the extra internal work)",
    "X2": "What may improve with dt={extension_dt} and substeps={extension_substeps}?",
}
# Config rule descriptions (by role) and the form's answer labels (by the label the form shows today) naming numbers.
CONFIG_TEMPLATES = {
    "extension": "the fifth contact case keeps every physical parameter and the {duration} s duration",
}
LABEL_TEMPLATES = {
    "samples 150": "samples {samples_fine}",
    "samples 75": "samples {samples_coarse}",
}
# The lab check's condition title that names the duration (rubric.check).
DURATION_CONDITION = "every contact case covers {duration} s, so sample count changes with dt"
SUMMARY = (
    "Your cube starts at {cube_start_z} m (edge {cube_size} m, density {cube_rho} kg/m³); the contact cases run "
    "{duration} s at dt {fine_dt} s and {coarse_dt} s with {base_substeps} and {more_substeps} substeps, the extension "
    "at dt {extension_dt} s with {extension_substeps} substeps; lane frictions {low_lane_friction} and "
    "{high_lane_friction}, launched at {launch_speed} m/s; table {table_friction}, exercise table "
    "{exercise_table_friction}."
)


def number(name: str, value: float | int) -> str:
    """A parameter as the lesson writes it: frictions with two decimals (0.50) or more when needed, substeps and
    densities as whole numbers, other quantities shortest but with a decimal point (1.0 m, 2.0 m/s, 0.005 s)."""
    knob = PARAMETERS.get(name)
    if isinstance(value, int):
        return str(value)
    if knob is not None and knob.unit == "1":
        two = f"{value:.2f}"
        return two if float(two) == value else f"{value:g}"
    shortest = f"{value:g}"
    if knob is not None and knob.unit == "kg/m^3" or any(c in shortest for c in ".e"):
        return shortest
    return shortest + ".0"  # a height or a speed as the lesson writes it: 1.0 m, 2.0 m/s


def text_values(variant: Variant | Mapping | None = None) -> dict[str, str]:
    """Every placeholder a template may use: each parameter, and the sample counts the parameters imply."""
    params = complete_parameters(variant.parameters if isinstance(variant, Variant) else variant)
    return dict(_values(tuple(sorted(params.items()))))


@functools.lru_cache(maxsize=64)
def _values(items: tuple) -> tuple:
    """Cached per parameter set: every graded item asks, and building the case table takes a fraction of a ms."""
    params = dict(items)
    cases = variant_cases(params)
    values = {name: number(name, value) for name, value in params.items()}
    values["samples_fine"] = str(cases["N1"].sample_count)
    values["samples_coarse"] = str(cases["N3"].sample_count)
    return tuple(values.items())


def placeholders(template: str) -> set[str]:
    return {field for _, field, _, _ in string.Formatter().parse(template) if field}


@functools.lru_cache(maxsize=4)
def _translations(lesson: str, locale: Locale) -> dict[str, dict[str, str]]:
    folder = rubrics.lesson_folder(lesson)
    path = folder / f"{lesson}.{locale}.yaml" if folder else None
    if path is None or not path.is_file():
        return {}
    data = yaml.safe_load(path.read_text(encoding="utf-8")) or {}
    return {section: dict(entries or {}) for section, entries in data.items() if section != "lesson"}


def translated(section: str, english: str, locale: Locale, lesson: str = "L03") -> str | None:
    """The locale's text for an English text or template (None where it has none; English is its own text)."""
    if locale == "en":
        return english
    return _translations(lesson, locale).get(section, {}).get(english)


def _render(template: str | None, variant, locale: Locale, section: str, fallback: str) -> str:
    """`template` in the locale with the variant's numbers; in English where the locale lacks it (as the pages show
    an untranslated text), never a translation carrying the lesson's numbers; `fallback` when there is no template."""
    if template is None:
        return fallback
    localized = translated(section, template, locale) or template
    return localized.format(**text_values(variant))


def item_question(item: Item, variant: Variant | None = None, locale: Locale = "en") -> str:
    """The question as this student reads it. English: the variant's numbers in the rubric's wording. Chinese: the
    same from the template's translation; without a variant or template, the lesson's translation of the rubric's
    question (or the English where it has none, as the pages do)."""
    template = QUESTION_TEMPLATES.get(item.id)
    if template is not None and template.format(**text_values(None)) != item.question:
        template = None  # this rubric version words the question otherwise: never show a stale template
    lesson_text = translated("questions", item.question, locale) or item.question
    if variant is None:
        return lesson_text
    return _render(template, variant, locale, "question_templates", lesson_text)


def questions(rubric: Rubric, variant: Variant | None = None, locale: Locale = "en") -> dict[str, str]:
    """Every item's question for this student, by item id."""
    return {item.id: item_question(item, variant, locale) for item in rubric.items}


def config_description(rubric: Rubric, role: str, variant: Variant | None = None, locale: Locale = "en") -> str:
    """A config rule's description for this student (the extension's names the variant's duration)."""
    description = rubric.configs[role].description
    template = CONFIG_TEMPLATES.get(role)
    if template is not None and template.format(**text_values(None)) != description:
        template = None
    lesson_text = translated("configs", description, locale) or description
    return lesson_text if variant is None else _render(template, variant, locale, "config_templates", lesson_text)


def answer_label(label: str, variant: Variant | None = None, locale: Locale = "en") -> str:
    """A form label for this student: 'samples 150' names the variant's count ('samples 400')."""
    lesson_text = translated("labels", label, locale) or label
    if variant is None:
        return lesson_text
    template = LABEL_TEMPLATES.get(label)
    if template is None:
        return lesson_text
    localized = translated("label_templates", template, locale)
    return lesson_text if localized is None else localized.format(**text_values(variant))


def duration_condition(variant: Variant | Mapping | None = None, locale: Locale = "en") -> str:
    """The lab check's duration condition with the variant's duration ('covers 1.5 s' for the lesson)."""
    return _render(DURATION_CONDITION, variant, locale, "condition_templates", DURATION_CONDITION)


def parameter_summary(variant: Variant | None = None, locale: Locale = "en") -> str:
    """One paragraph stating every parameter of the student's lab (the lesson's own when no variant)."""
    return _render(SUMMARY, variant, locale, "variant_summary", SUMMARY.format(**text_values(None)))


def parameter_rows(variant: Variant | None = None, locale: Locale = "en") -> list[tuple[str, str, str, bool]]:
    """(name, what it is, value with unit, whether it differs from the lesson) for a table of the student's values."""
    params = complete_parameters(variant.parameters if variant else None)
    shipped, values = shipped_parameters(), text_values(variant)
    rows = []
    for name, knob in PARAMETERS.items():
        label = translated("parameters", knob.description, locale) or knob.description
        unit = "" if knob.unit in ("1", "substeps") else " " + knob.unit.replace("^3", "³")
        rows.append((name, label, values[name] + unit, params[name] != shipped[name]))
    return rows
