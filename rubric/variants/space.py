"""A lesson's variant space as reviewed data: which parameters vary, over which values, under which constraints.

One file per version, `rubric/lessons/L03-lab-variants-vN.yaml`, beside the rubric version it was reviewed for
(`grading_rubric`), versioned and reviewed as tolerances are (rubric.governance.publish_variant_space): every parameter
and constraint carries its rationale, reviewer and date, a used version is immutable, a change needs a new version
with a fresh review of what changed. A rubric version with no variant file has no variants: it grades as it always did.
"""

from __future__ import annotations

import datetime as dt
import functools
import hashlib
import json
import re
from collections.abc import Mapping
from decimal import Decimal
from typing import Annotated

import yaml
from pydantic import Field, model_validator
from pydantic_core import PydanticCustomError

from .. import rubrics
from ..rubrics import VERSION_PATTERN, ReviewRecord, RubricModel, version_key
from .expr import RuleError, evaluate_rule, parse_rule, rule_names
from .parameters import PARAMETERS, fixed_quantities, shipped_parameters

# A space lists its values; past this many per parameter it is a continuum nobody reviewed value by value.
MAX_VALUES = 200
Name = Annotated[str, Field(pattern=r"^[a-z][a-z0-9_]*$", max_length=64)]
Number = float | int


class Reviewed(RubricModel):
    """Why a declaration holds, who checked it and when: the same record a tolerance carries."""

    rationale: Annotated[str, Field(min_length=20)]
    reviewer: Annotated[str, Field(min_length=1, max_length=128)]
    review_date: dt.date


class Range(RubricModel):
    """min, min + step, ... up to max (inclusive when it falls on a step), computed in decimal, never float drift."""

    min: Number
    max: Number
    step: Annotated[Number, Field(gt=0)]


class ParameterSpace(Reviewed):
    """The values one parameter may take: an explicit list of choices, or a range with a step; exactly one of them."""

    unit: Annotated[str, Field(min_length=1, max_length=16)]
    choices: Annotated[list[Number], Field(min_length=1)] | None = None
    range: Range | None = None

    def values(self, kind: str = "float") -> tuple[Number, ...]:
        if self.choices is not None:
            raw = [Decimal(str(v)) for v in self.choices]
        else:
            lo, hi, step = (Decimal(str(v)) for v in (self.range.min, self.range.max, self.range.step))
            raw, value = [], lo
            while value <= hi and len(raw) <= MAX_VALUES:
                raw.append(value)
                value += step
        return tuple(int(v) if kind == "int" else float(v) for v in raw)


class Constraint(Reviewed):
    """A rule every variant must satisfy (rubric.variants.expr), e.g. `low_lane_friction < table_friction`."""

    rule: Annotated[str, Field(min_length=1, max_length=500)]


def known_names() -> frozenset[str]:
    return frozenset(PARAMETERS) | frozenset(fixed_quantities())


@functools.lru_cache(maxsize=256)
def compiled(rule: str):
    return parse_rule(rule, set(known_names()))


class VariantSpace(RubricModel):
    """The variant space of one lesson, at one version, for one grading rubric version."""

    lesson: Annotated[str, Field(pattern=r"^L[0-9]{2}$")]
    version: Annotated[str, Field(pattern=VERSION_PATTERN)]
    grading_rubric: Annotated[str, Field(pattern=VERSION_PATTERN)]
    engine_version: str
    review: ReviewRecord
    parameters: Annotated[dict[Name, ParameterSpace], Field(min_length=1)]
    constraints: dict[Name, Constraint] = {}

    @model_validator(mode="after")
    def _valid(self) -> "VariantSpace":
        for name, space in self.parameters.items():
            _check_parameter(name, space)
        shipped = self.fill(shipped_parameters())
        for name, c in self.constraints.items():
            try:
                compiled(c.rule)
            except RuleError as exc:
                raise PydanticCustomError("constraint_rule", "constraints.{name}.rule: {why}",
                                          {"name": name, "why": str(exc)}) from None
            if not evaluate_rule(compiled(c.rule), shipped):
                # A rule the lesson's own parameters break was written the wrong way round, or excludes the lesson.
                raise PydanticCustomError(
                    "constraint_excludes_lesson",
                    "constraints.{name}: the lesson's shipped parameters break this rule ({detail}); a constraint "
                    "states what the lesson needs, so the lesson itself must satisfy it",
                    {"name": name, "detail": describe_values(c.rule, shipped)})
        return self

    def fill(self, values: Mapping[str, Number]) -> dict[str, Number]:
        """`values` over the shipped parameters, plus the fixed quantities a rule may read."""
        return fixed_quantities() | shipped_parameters() | dict(values)

    def choices(self) -> dict[str, tuple[Number, ...]]:
        """Each varying parameter's values, typed as the parameter is (substeps are whole numbers)."""
        return {name: space.values(PARAMETERS[name].kind) for name, space in self.parameters.items()}

    def violations(self, values: Mapping[str, Number]) -> list[str]:
        """Every constraint `values` break, as 'name: rule (the values it read)'; empty when all hold."""
        full = self.fill(values)
        return [f"{name}: {describe_values(c.rule, full)}" for name, c in self.constraints.items()
                if not evaluate_rule(compiled(c.rule), full)]

    @property
    def content_hash(self) -> str:
        return hashlib.sha256(canonical_json(self).encode()).hexdigest()


def describe_values(rule: str, values: Mapping[str, Number]) -> str:
    shown = ", ".join(f"{n}={values[n]:g}" for n in rule_names(compiled(rule)))
    return f"{rule} is false with {shown}"


def _check_parameter(name: str, space: ParameterSpace) -> None:
    where = f"parameters.{name}"
    knob = PARAMETERS.get(name)
    if knob is None:
        raise PydanticCustomError("unknown_parameter", "{where}: unknown parameter; the lesson's parameters are {known}",
                                  {"where": where, "known": ", ".join(PARAMETERS)})
    if (space.choices is None) == (space.range is None):
        raise PydanticCustomError("choices_or_range", "{where}: give exactly one of choices or range", {"where": where})
    if space.unit != knob.unit:
        raise PydanticCustomError("unit", "{where}.unit: {unit}, but {name} is measured in {want}",
                                  {"where": where, "unit": repr(space.unit), "name": name, "want": repr(knob.unit)})
    if space.range is not None:
        r = space.range
        if r.min > r.max:
            raise PydanticCustomError("range_order", "{where}.range: min {lo} is above max {hi}",
                                      {"where": where, "lo": r.min, "hi": r.max})
    raw = space.choices if space.choices is not None else [space.range.min, space.range.max, space.range.step]
    if knob.kind == "int" and any(isinstance(v, float) and not v.is_integer() for v in raw):
        raise PydanticCustomError("whole_number", "{where}: {name} takes whole numbers, got {raw}",
                                  {"where": where, "name": name, "raw": raw})
    values = space.values(knob.kind)
    if len(values) > MAX_VALUES:
        raise PydanticCustomError("too_many_values", "{where}: more than {cap} values; list fewer or take a larger step",
                                  {"where": where, "cap": MAX_VALUES})
    if len(set(values)) != len(values):
        raise PydanticCustomError("duplicate_values", "{where}.choices: duplicate values {v}",
                                  {"where": where, "v": list(values)})
    outside = [v for v in values if not knob.low <= v <= knob.high]
    if outside:
        raise PydanticCustomError("outside_bounds", "{where}: values {v} outside what the case schema accepts, "
                                  "[{lo}, {hi}] {unit}",
                                  {"where": where, "v": outside, "lo": f"{knob.low:g}", "hi": f"{knob.high:g}",
                                   "unit": knob.unit})


def canonical_json(space: VariantSpace) -> str:
    return json.dumps(space.model_dump(mode="json"), sort_keys=True, separators=(",", ":"))


def parse_variant_space(data: Mapping) -> VariantSpace:
    """A variant space from JSON-like data (a lesson file or a stored version); dates may be ISO strings."""
    return VariantSpace.model_validate_json(json.dumps(data, default=str))


def variant_space_versions(lesson: str = "L03") -> list[str]:
    """Variant space versions shipped for a lesson, oldest first (files named LESSON-lab-variants-vVERSION.yaml)."""
    pattern = re.compile(rf"^{re.escape(lesson)}-lab-variants-v([0-9.]+)\.yaml$")
    folder = rubrics.lesson_folder(lesson)
    found = [m.group(1) for p in folder.glob("*.yaml") if (m := pattern.match(p.name))] if folder else []
    return sorted((v for v in found if re.match(VERSION_PATTERN, v)), key=version_key)


def load_variant_space(lesson: str = "L03", version: str | None = None) -> VariantSpace:
    """A lesson's variant space at `version`, or its latest; the file's lesson and version must agree with its name,
    and the rubric version it was reviewed for must exist."""
    versions = variant_space_versions(lesson)
    if not versions:
        raise LookupError(f"no variant space files for lesson {lesson!r} in "
                          f"{rubrics.lesson_folder(lesson) or 'no installed lesson'}")
    version = version or versions[-1]
    if version not in versions:
        raise LookupError(f"lesson {lesson} has no variant space version {version!r}; known: {', '.join(versions)}")
    data = yaml.safe_load((rubrics.lesson_folder(lesson) / f"{lesson}-lab-variants-v{version}.yaml").read_text())
    space = parse_variant_space(data)
    if (space.lesson, space.version) != (lesson, version):
        raise ValueError(f"{lesson}-lab-variants-v{version}.yaml declares lesson {space.lesson} version {space.version}")
    if space.grading_rubric not in rubrics.rubric_versions(lesson):
        raise ValueError(f"{lesson}-lab-variants-v{version}.yaml: grading_rubric {space.grading_rubric!r} is not a "
                         f"published rubric version of {lesson}")
    return space


def variant_space_for(rubric: rubrics.Rubric) -> VariantSpace | None:
    """The latest variant space reviewed for this rubric version, or None: then there are no variants and every
    student grades on the lesson's shipped cases, exactly as before variants existed."""
    for version in reversed(variant_space_versions(rubric.lesson)):
        space = load_variant_space(rubric.lesson, version)
        if space.grading_rubric == rubric.version:
            return space
    return None
