"""The prediction sheet as a form: its inputs generated from the sheet's typed model (rubric.sheet) and the lesson's
rubric, never written per question; form values to the sheet the API takes and back; the same validation as a
submission (grader.services.submissions.sheets); the configs' field-by-field difference from the lesson's baseline.

A form input is named by its path in the sheet (`answers.C1.substep_dt.value`), so every server message, which names
that path, lands beside its input.

A student at an assignment with a variant pool (issue 34) fills the form of their own lab (`form_variant`): the
questions and A1's labels name their numbers (rubric.variants.texts), the config editor starts from their variant's
baseline (rubric.one_factor.role_baseline) and the one-factor check compares with it. Staff and free sheets keep the
lesson's shipped parameters.
"""

from __future__ import annotations

import math
import re
import types
import typing
import dataclasses
from dataclasses import dataclass
from typing import Any, Literal

import yaml
from pydantic import BaseModel, ValidationError
from sqlalchemy import select
from sqlalchemy.orm import Session

import rubric
from grader.core import content_key
from grader.core.lifecycle import stored_result
from grader.core.states import AssignmentParts
from grader.core.models import Assignment, CaseRun, Measurement, User
from grader.services.identity import access
from grader.services.setup import student_variants
from grader.services.submissions import sheets
from grader.services.errors import Invalid, field_errors
from rubric import Variant, describe_errors, one_factor_findings, sheet_files
from rubric.lesson import Lesson, lesson
from rubric.one_factor import role_baseline
from rubric.rubrics import Rubric
from rubric.sheet import PredictionSheet, Quantity
from rubric.variants import texts

# The lesson of a free sheet (one answered outside any assignment): the service's first lesson. An assignment's form
# is its own lesson's, read from the lesson's declaration (rubric.lesson) as everything below is.
LESSON = typing.get_args(PredictionSheet.model_fields["lesson"].annotation)[0]


def form_configs(book: Rubric) -> tuple[str, ...]:
    """The configs a student edits in the form (the rest travel in the YAML only): each starts from its rule's
    baseline. Those every whole sheet of the rubric's lesson submits."""
    return lesson(book.lesson).form_configs()
# Config fields that are no physics a student chooses: the case kind, and staff-only or evidence switches.
HIDDEN_CONFIG_FIELDS = ("kind", "backend", "render")
YAML_MAX_DEPTH = 32
INTEGER_TEXT = re.compile(r"^[+-]?[0-9]+$")


@dataclass(frozen=True)
class Input:
    """One answer field: `name` is its sheet path; `widget` says how it is asked."""

    name: str
    label: str
    widget: Literal["radio", "checkbox", "number", "integer", "text", "textarea", "quantity", "stop"]
    choices: tuple[str, ...] = ()
    units: tuple[str, ...] = ()
    required: bool = True
    default: Any = None


@dataclass(frozen=True)
class ItemForm:
    id: str
    question: str  # the rubric's (English; the page translates it), or the student's variant's in their locale
    part: str
    inputs: tuple[Input, ...]
    localized: bool = False  # `question` is already in the reader's locale (a variant's text): never translated again


def form_variant(*, session: Session, assignment: Assignment | None, user: User) -> Variant | None:
    """The variant whose lab this form is for: a student's own at an assignment with a variant pool, fixed at this
    first view (grader.services.setup.student_variants; committed, so a later submission meets the same one); None
    for a free sheet, staff and an assignment without a pool. Conflict while the pool is not ready."""
    if assignment is None or not access.is_student(user):
        return None
    variant = student_variants.student_variant(session=session, assignment=assignment, student=user)
    if variant is not None:
        session.commit()
    return variant


def _choices(annotation) -> tuple[str, ...] | None:
    """A Literal's (or bool's) values as form strings; None for any other type."""
    if annotation is bool:
        return ("true", "false")
    if typing.get_origin(annotation) is Literal:
        return tuple(str(v) for v in typing.get_args(annotation))
    return None


def _union(annotation) -> tuple | None:
    return typing.get_args(annotation) if typing.get_origin(annotation) in (typing.Union, types.UnionType) else None


def answer_inputs(model: type[BaseModel], prefix: str) -> list[Input]:
    """One Input per answer field of `model`, walked through its nested models. A field type this does not know is a
    TypeError: a new kind of answer fails the tests until the form can ask it."""
    out = []
    fields = sorted(model.model_fields.items(), key=lambda pair: pair[0] == "explanation")  # the answer, then why
    for name, info in fields:
        path, annotation = f"{prefix}.{name}", info.annotation
        label = " ".join(path.split(".")[2:]).replace("_", " ")  # within its item: "baseline low", not "low"
        extra = {} if info.is_required() else {"required": False, "default": info.get_default()}
        arms = _union(annotation)
        if name == "explanation":
            out.append(Input(path, "explanation (optional, never scored)", "textarea", **extra))
        elif (choices := _choices(annotation)) is not None:
            out.append(Input(path, label, "radio", choices, **extra))
        elif typing.get_origin(annotation) is list and (choices := _choices(typing.get_args(annotation)[0])):
            out.append(Input(path, label, "checkbox", choices, **extra))
        elif annotation is float:
            out.append(Input(path, label, "number", **extra))
        elif annotation is int:
            out.append(Input(path, label, "integer", **extra))
        elif annotation is str:
            out.append(Input(path, label, "text", **extra))
        elif isinstance(annotation, type) and issubclass(annotation, Quantity):
            units = _choices(annotation.model_fields["unit"].annotation)
            out.append(Input(path, label, "quantity", units=units, **extra))
        elif arms and len(arms) == 2 and any(isinstance(a, type) and issubclass(a, Quantity) for a in arms):
            quantity = next(a for a in arms if isinstance(a, type) and issubclass(a, Quantity))
            (other,) = _choices(next(a for a in arms if a is not quantity))
            units = _choices(quantity.model_fields["unit"].annotation)
            out.append(Input(path, label, "stop", (other,), units, **extra))
        elif isinstance(annotation, type) and issubclass(annotation, BaseModel):
            out.extend(answer_inputs(annotation, path))
        else:
            raise TypeError(f"{path}: the sheet form has no input for {annotation!r}")
    return out


def item_forms(book: Rubric, item_ids: list[str], variant: Variant | None = None, locale: str = "en"
               ) -> list[ItemForm]:
    """The form of each of the assignment's items: its question from the rubric (under a variant, with the variant's
    numbers in `locale`: rubric.variants.texts), its inputs from the answer model."""
    def question(item_id: str) -> str:
        item = book.item(item_id)
        return item.question if variant is None else texts.item_question(item, variant, locale)

    answers = lesson(book.lesson).answers_model()
    return [ItemForm(i, question(i), book.item(i).part,
                     tuple(answer_inputs(answers.model_fields[i].annotation, f"answers.{i}")), variant is not None)
            for i in item_ids]


def answer_label(label: str, variant: Variant | None, locale: str) -> str:
    """An answer input's label as a student on `variant` reads it ('samples 150' names their count) in `locale`."""
    return texts.answer_label(label, variant, locale)


# --- configs ----------------------------------------------------------------------------------------------------------

def config_baseline(book: Rubric, role: str, variant: Variant | None = None):
    """The lesson case a config role's form starts from: its one-factor rule's baseline, the variant's when given (a
    variant is a pool's, and pools are of the lesson with a variant space)."""
    if variant is None:
        return lesson(book.lesson).cases[book.configs[role].baseline]
    return role_baseline(role, book, variant)


def _dump(spec) -> dict:
    return spec.model_dump(mode="json", exclude_computed_fields=True)


def flatten(value: Any, prefix: str) -> dict[str, Any]:
    """Nested dicts and lists as dotted paths (`table.pos.2`, `lanes.0.friction`) to their leaves."""
    if isinstance(value, dict):
        return {k: v for key, item in value.items() for k, v in flatten(item, f"{prefix}.{key}").items()}
    if isinstance(value, list):
        return {k: v for i, item in enumerate(value) for k, v in flatten(item, f"{prefix}.{i}").items()}
    return {prefix: value}


def _merge(base: Any, over: Any) -> Any:
    if isinstance(base, dict) and isinstance(over, dict):
        return {**base, **{k: _merge(base.get(k), v) for k, v in over.items()}}
    return over


def config_values(book: Rubric, role: str, sheet: dict, variant: Variant | None = None) -> dict[str, Any]:
    """A config's fields as the form shows them: the draft's own over its baseline (the variant's when given; named
    after the role), by path."""
    base = _dump(config_baseline(book, role, variant)) | {"name": role}
    own = sheet.get("configs", {}).get(role) if isinstance(sheet.get("configs"), dict) else None
    merged = _merge(base, own) if isinstance(own, dict) else base
    return flatten({k: v for k, v in merged.items() if k not in HIDDEN_CONFIG_FIELDS}, f"configs.{role}")


def _field_choices(spec_type: type[BaseModel], path: str) -> tuple[str, ...]:
    """A top-level config field's choices when its type is a Literal (precision "32" or "64"); else none."""
    info = spec_type.model_fields.get(path)
    return (_choices(info.annotation) or ()) if info is not None and "." not in path else ()


def may_change(book: Rubric, role: str, path: str) -> bool:
    """Whether the role's one-factor rule lets the config field at `path` (`table.friction`) differ from its
    baseline."""
    return any(path == field or path.startswith(field + ".") for field in book.configs[role].may_change)


def config_inputs(book: Rubric, role: str, sheet: dict, variant: Variant | None = None) -> list[Input]:
    """One input per field of the config, in the form `configs.ROLE.table.friction`: the baseline case's fields (the
    variant's baseline when given), and any more the draft has (a third lane from a YAML), each asked as its baseline
    value's type (a float field stays a float field whatever the draft holds), its choices where the field has them."""
    widgets = {bool: "radio", int: "integer", float: "number"}
    baseline = config_baseline(book, role, variant)
    defaults = flatten(_dump(baseline), f"configs.{role}")
    inputs = []
    for name, value in config_values(book, role, sheet, variant).items():
        path = name.removeprefix(f"configs.{role}.")
        typed = defaults.get(name, value)
        if isinstance(value, bool) or isinstance(typed, bool):
            widget, choices = "radio", ("true", "false")
        elif choices := _field_choices(type(baseline), path):
            widget = "radio"
        else:
            widget, choices = widgets.get(type(typed), "text"), ()
        inputs.append(Input(name, path, widget, choices, default=defaults.get(name)))
    return inputs


# --- form values <-> sheet --------------------------------------------------------------------------------------------

def _number(text: str, integer: bool) -> Any:
    """The number typed, or the text itself when it is none: the sheet's own validation then names the field. A
    whole number typed where a float is asked stays an integer (`1`, not `1.0`), so a sheet's YAML comes back from
    the form with the types it went in with; the sheet's float fields take it as it is."""
    text = text.strip()
    try:
        value = int(text) if integer or INTEGER_TEXT.match(text) else float(text)
    except ValueError:  # not a number, or more digits than Python reads (rubric.sheet_files.MAX_INTEGER_DIGITS)
        return text
    # An integer is finite whatever its size (math.isfinite of one past a float's range raised: a 500)
    return value if isinstance(value, int) or math.isfinite(value) else text


def _get(data: Any, path: str) -> Any:
    for key in path.split("."):
        if isinstance(data, dict):
            data = data.get(key)
        elif isinstance(data, list) and key.isdigit() and int(key) < len(data):
            data = data[int(key)]
        else:
            return None
    return data


def _put(data: dict, path: str, value: Any) -> None:
    keys = path.split(".")
    for key in keys[:-1]:
        if not isinstance(data.get(key), dict):  # never a 500: a path through a value (the caps refuse such keys)
            data[key] = {}
        data = data[key]
    data[keys[-1]] = value


def _listify(value: Any) -> Any:
    """Dicts keyed 0..n-1 (from `lanes.0.friction` paths) back into lists."""
    if isinstance(value, dict):
        value = {k: _listify(v) for k, v in value.items()}
        if value and all(k.isdigit() for k in value) and sorted(map(int, value)) == list(range(len(value))):
            return [value[str(i)] for i in range(len(value))]
    return value


def _answer(form, field: Input) -> tuple[bool, Any]:
    """(given, value) of one answer input from the posted form (`form.get`, `form.getlist`)."""
    def get(suffix: str = "") -> str:
        return (form.get(field.name + suffix) or "").strip()

    if field.widget == "checkbox":
        return True, form.getlist(field.name)
    if field.widget == "radio":
        value = get()
        if field.choices == ("true", "false"):
            return bool(value), {"true": True, "false": False}.get(value, value)
        return bool(value), value
    if field.widget in ("number", "integer"):
        return bool(get()), _number(get(), field.widget == "integer")
    if field.widget in ("text", "textarea"):
        return bool(get()), get()
    kind = get(".kind") if field.widget == "stop" else "value"
    if kind in field.choices:
        return True, kind
    quantity = {"value": _number(get(".value"), False), "unit": get(".unit")}
    return bool(get(".value")), quantity


def sheet_from_form(form, *, items: list[ItemForm], book: Rubric | None, previous: dict,
                    variant: Variant | None = None) -> dict:
    """The sheet the form holds, in the API's shape. An optional field is written when it differs from its default or
    the draft already had it, so a sheet imported from YAML comes back out as it went in. `variant`: the student's,
    whose baseline the config editor showed."""
    sheet: dict[str, Any] = {"lesson": book.lesson if book is not None else LESSON,
                             "student": (form.get("student") or "").strip()}
    for item in items:
        for field in item.inputs:
            given, value = _answer(form, field)
            if field.widget == "checkbox" and not field.required and value == field.default \
                    and _get(previous, field.name) is None:
                continue
            if field.widget == "checkbox" and isinstance(before := _get(previous, field.name), list):
                # a list's order is the draft's (the form posts in the choices' order): its YAML comes back as it was
                value = [v for v in before if v in value] + [v for v in value if v not in before]
            if given:
                _put(sheet, field.name, value)
        sheet.setdefault("answers", {}).setdefault(item.id, {})
    if book is not None:
        sheet["configs"] = _configs_from_form(form, book, previous, variant)
    return sheet


def _configs_from_form(form, book: Rubric, previous: dict, variant: Variant | None = None) -> dict:
    before = previous.get("configs") if isinstance(previous.get("configs"), dict) else {}
    edited = form_configs(book)
    configs = {role: spec for role, spec in before.items() if role not in edited}  # YAML-only roles travel on
    for role in edited:
        # A field left out of a config takes the case schema's default, which is the lesson's shipped value: so the
        # fields written are those that differ from the shipped baseline, under a variant too (its cube edge, say,
        # is written; a field put back to the shipped value is left out and reads as that value).
        baseline = _dump(config_baseline(book, role))
        posted: dict[str, Any] = {}
        for field in config_inputs(book, role, previous, variant):
            text = (form.get(field.name) or "").strip()
            value = ({"true": True, "false": False}.get(text, text) if field.widget == "radio"
                     else _number(text, field.widget == "integer") if field.widget in ("number", "integer") else text)
            _put(posted, field.name.removeprefix(f"configs.{role}."), value)
        posted = _listify(posted)
        own = before.get(role) if isinstance(before.get(role), dict) else {}
        config = {"kind": baseline["kind"], "name": posted.pop("name", role)}
        # A top-level field goes whole (a table with its size and position, not its friction alone, which would
        # take Table's defaults for the rest): when it differs from the baseline, or the draft already had it.
        config |= {key: value for key, value in posted.items() if value != baseline.get(key) or key in own}
        config |= {key: own[key] for key in HIDDEN_CONFIG_FIELDS if key in own and key != "kind"}
        configs[role] = config
    return configs


def form_state(sheet: dict, items: list[ItemForm], book: Rubric | None, variant: Variant | None = None
               ) -> dict[str, Any]:
    """What each input shows for a sheet (a draft): form strings by input name (lists for checkboxes); a config's
    fields the draft leaves out show the baseline of `variant` (the student's) when given."""
    values: dict[str, Any] = {"student": sheet.get("student") or ""}
    for item in items:
        for field in item.inputs:
            values |= _shown(field, _get(sheet, field.name))
    if book is not None:
        for role in form_configs(book):
            values |= {k: _text(v) for k, v in config_values(book, role, sheet, variant).items()}
    return values


def form_text(value: Any) -> str:
    """A sheet's value as its input shows it: floats as Python writes them (0.5, 1.0), integers as integers."""
    return _text(value)


def _text(value: Any) -> str:
    if value is None:
        return ""
    if isinstance(value, bool):
        return "true" if value else "false"
    return repr(value) if isinstance(value, float) else str(value)


def _shown(field: Input, value: Any) -> dict[str, Any]:
    if field.widget == "checkbox":
        return {field.name: [str(v) for v in value] if isinstance(value, list) else []}
    if field.widget in ("quantity", "stop"):
        if isinstance(value, str):
            return {f"{field.name}.kind": value}
        value = value if isinstance(value, dict) else {}
        return {f"{field.name}.kind": "value" if value else "", f"{field.name}.value": _text(value.get("value")),
                f"{field.name}.unit": _text(value.get("unit"))}
    return {field.name: _text(value)}


# --- checking ---------------------------------------------------------------------------------------------------------

def problems(sheet: dict, part: str) -> list[dict[str, str]]:
    """The submission's own rules (grader.services.submissions.sheets.parse_sheet) on the sheet: [{field: 'sheet.…', rule}], as
    the API answers them; empty when it would be taken."""
    try:
        sheets.parse_sheet(sheet, part)
    except ValidationError as exc:
        return field_errors(describe_errors(exc), prefix="sheet")
    return []


def by_input(errors: list[dict[str, str]], names: list[str]) -> tuple[dict[str, list[str]], list[dict[str, str]]]:
    """Each error beside the input it names (the longest input name its field starts with, dot by dot); the rest
    unplaced. Looked up in a set, path prefix by path prefix: linear in the errors, whatever the number of inputs."""
    known = set(names)
    placed: dict[str, list[str]] = {}
    rest = []
    for error in errors:
        owner = _owner(error["field"].removeprefix("sheet."), known)
        if owner is None:
            rest.append(error)
        else:
            placed.setdefault(owner, []).append(error["rule"])
    return placed, rest


def _owner(path: str, names: set[str]) -> str | None:
    """The longest of `names` that is `path` or a dotted prefix of it."""
    while path not in names:
        cut = path.rfind(".")
        if cut < 0:
            return None
        path = path[:cut]
    return path


@dataclass
class ConfigCheck:
    """One config against its baseline: every changed field, those the rule forbids, and the items it would void."""

    role: str
    baseline: str
    may_change: list[str]
    changes: list = dataclasses.field(default_factory=list)
    violations: list = dataclasses.field(default_factory=list)
    verdict: str = ""
    voids: list[str] = dataclasses.field(default_factory=list)


def config_checks(*, session: Session, sheet: dict, part: str, book: Rubric, variant: Variant | None = None
                  ) -> tuple[list[ConfigCheck], list[dict[str, str]]]:
    """The one-factor verdict the grader will apply (rubric.one_factor_findings) on the sheet's configs, against the
    baselines of `variant` (the student's) when given, whatever the answers hold yet, with the items each broken config
    would void where that can be told; and the configs' own errors."""
    declared = lesson(book.lesson)
    try:
        configs = declared.configs_model().model_validate(sheet.get("configs") or {})
    except ValidationError as exc:
        return [], field_errors(describe_errors(exc), prefix="sheet.configs")
    probe = declared.sheet_model.model_construct(lesson=book.lesson, student="", answers=None, configs=configs)
    findings = one_factor_findings(probe, book, variant)
    voids = _voided(session, sheet, part, book, variant) if any(not f.ok for f in findings.values()) else {}
    return [ConfigCheck(role=role, baseline=f.baseline, may_change=f.may_change, changes=f.changes,
                        violations=f.violations, verdict=f.describe(), voids=voids.get(f.describe(), []))
            for role, f in findings.items()], []


def _voided(session: Session, sheet: dict, part: str, book: Rubric, variant: Variant | None = None
            ) -> dict[str, list[str]]:
    """Item ids by the finding that voids them: the sheet graded as the grader would, on the lesson's cases as stored
    (the variant's, when given). A config fault voids the items whose scoring rules read its run, which only running
    the rules tells; empty while the sheet is invalid or a lesson case was never measured (such a rule would stop there
    first)."""
    try:
        parsed = sheets.parse_sheet(sheet, part)
    except ValidationError:
        return {}
    results = _lesson_results(session, lesson(book.lesson), variant)
    return _voids_of(parsed, results, book, variant) if results is not None else {}


def _lesson_results(session: Session, declared: Lesson, variant: Variant | None = None) -> dict | None:
    """The lesson's own cases as stored (their results by name), under `variant` when given (its pool measured them),
    or None while one was never measured."""
    results = {}
    for spec in declared.lesson_run_specs(variant):
        name = spec.name
        inputs = content_key.key_inputs(spec.model_dump(mode="json", exclude_computed_fields=True),
                                        backend=spec.backend, precision=spec.precision)
        found = session.scalar(select(Measurement).where(Measurement.content_key == content_key.content_key(inputs)))
        run = session.get(CaseRun, found.case_run_id) if found is not None else None
        if run is None:
            return None
        try:
            results[name] = stored_result(run)
        except LookupError:
            return None
    return results


def _voids_of(parsed: PredictionSheet, results: dict, book: Rubric, variant: Variant | None = None
              ) -> dict[str, list[str]]:
    voided: dict[str, list[str]] = {}
    for item in rubric.grade_sheet(parsed, results, book, variant).items:
        if item.verdict == "one_factor_violation":  # the rule stopped at the broken config, its finding as measured
            voided.setdefault(item.measured, []).append(item.id)
    return voided


def held_voids(*, session: Session, sheet: dict, part: str, book: Rubric, variant: Variant | None = None
               ) -> dict[str, list[str]]:
    """For each config the form edits, the items the grader would void if one of its held fields changed (any one:
    a broken config is never run, so every item reading its run is voided alike). Told by grading the sheet with
    that config's seed moved, on the lesson's cases as stored (the variant's, when given); a role is absent while the
    sheet is invalid or the lesson's cases were never measured."""
    if not isinstance(sheet.get("configs"), dict):
        return {}
    try:
        sheets.parse_sheet(sheet, part)
    except ValidationError:
        return {}
    results = _lesson_results(session, lesson(book.lesson), variant)
    if results is None:
        return {}
    out = {}
    for role in form_configs(book):
        own = sheet["configs"].get(role)
        if not isinstance(own, dict) or may_change(book, role, "seed"):
            continue
        probe = dict(sheet, configs={**sheet["configs"], role: {**own, "seed": int(own.get("seed") or 0) + 1}})
        try:
            parsed = sheets.parse_sheet(probe, part)
        except (ValidationError, TypeError, ValueError):
            continue
        out[role] = sorted({i for finding, ids in _voids_of(parsed, results, book, variant).items()
                            if finding.startswith(f"{role} vs ") for i in ids})
    return out


# --- YAML -------------------------------------------------------------------------------------------------------------

# libyaml's C emitter where PyYAML was built with it (the pure-Python one is slower); the same safe types either way.
_DUMPER = getattr(yaml, "CSafeDumper", yaml.SafeDumper)


def _plain(value: Any, depth: int = 0) -> str | None:
    """Why the loaded YAML is not plain sheet data (too deep, a non-finite number, a non-text key), or None."""
    if depth > YAML_MAX_DEPTH:
        return f"nested more than {YAML_MAX_DEPTH} levels deep"
    if isinstance(value, float) and not math.isfinite(value):
        return "numbers must be finite (no .nan or .inf)"
    if isinstance(value, dict):
        if not all(isinstance(k, str) for k in value):
            return "every key must be text"
        return next((why for v in value.values() if (why := _plain(v, depth + 1))), None)
    if isinstance(value, list):
        return next((why for v in value if (why := _plain(v, depth + 1))), None)
    if value is None or isinstance(value, str | int | float | bool):
        return None
    return f"{type(value).__name__} values are not sheet data"


def sheet_from_yaml(text: str) -> dict:
    """A sheet from the YAML the API takes (`grader submit` reads it with the same rubric.sheet_files); Invalid naming
    the field (its path in the sheet, or the file) and the rule."""
    try:  # no aliases (a few aliased lines can stand for gigabytes once stored as JSON), no deep nesting, and no
        # number the service cannot hold (a 5000-digit integer, 1:59:59), each named by its path, before loading
        data = sheet_files.load_yaml(text, max_depth=YAML_MAX_DEPTH, aliases=False)
    except sheet_files.SheetTextError as exc:
        raise Invalid("invalid YAML", [{"field": exc.field, "rule": exc.rule}]) from None
    if not isinstance(data, dict):
        raise Invalid("invalid YAML", [{"field": "file", "rule": "must hold one mapping: lesson, student, answers, "
                                                                  "configs"}])
    if (why := _plain(data)) is not None:
        raise Invalid("invalid YAML", [{"field": "file", "rule": why}])
    sheets.check_size(data, detail="invalid YAML")
    return data


def sheet_yaml(sheet: dict) -> str:
    return yaml.dump(sheet, Dumper=_DUMPER, sort_keys=False, allow_unicode=True)


def has_configs(part: str) -> bool:
    return part != AssignmentParts.CHECKPOINTS
