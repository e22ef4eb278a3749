"""The L03 prediction sheet: typed answers to every question of the lesson, plus the student's modified case configs.

Strict on purpose: unknown question ids, missing answers, wrong types ("0.5" for a number, "yes" for a boolean) and
a wrong lesson are errors whose location names the item (e.g. `answers.A3.agree`), never coerced or dropped.
Every answer may carry a free-text `explanation`, kept for the instructor and never scored.
The one-factor rule that each submitted config must obey is rubric.one_factor.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator
from pydantic_core import PydanticCustomError

from .cases import BASELINE_CASES
from .specs import ContactCase, FrictionCase

CaseName = Literal["N1", "N2", "N3", "N4"]
LaneName = Literal["low", "high"]
# Direction of a lane's stopping-distance change; of the penetration proxy when substeps increase.
DistanceChange = Literal["farther", "shorter", "unchanged"]
ProxyChange = Literal["decrease", "increase", "unchanged"]
Layer = Literal["physical", "numerical", "observational", "visual"]
Diagnostic = Literal[
    "finite_state", "penetration_proxy", "contact_presence", "geometric_separation",
    "upward_velocity", "tail_settling_error", "full_trajectory",
]
# Units a student may report in; converted to SI before any comparison.
_SCALE = {"s": 1.0, "ms": 1e-3, "m": 1.0, "cm": 1e-2, "mm": 1e-3}


class SheetModel(BaseModel):
    model_config = ConfigDict(extra="forbid", strict=True, frozen=True)


class Answer(SheetModel):
    explanation: Annotated[str | None, Field(max_length=4000)] = None


class Quantity(SheetModel):
    """A number with its unit, e.g. {value: 5, unit: ms}."""

    value: Annotated[float, Field(allow_inf_nan=False)]
    unit: Literal["s", "ms", "m", "cm", "mm"]

    @property
    def si(self) -> float:
        return self.value * _SCALE[self.unit]


class TimeQuantity(Quantity):
    unit: Literal["s", "ms"]


class LengthQuantity(Quantity):
    unit: Literal["m", "cm", "mm"]


StopReport = LengthQuantity | Literal["not_stopped"]


def _unique(values: list) -> list:
    if len(set(values)) != len(values):
        raise PydanticCustomError("unique", "entries must be unique, got {v}", {"v": values})
    return values


# Lists are capped at their number of possible distinct entries, and counts at far beyond any L03 case, so an absurd
# answer is refused naming its field rather than stored (or echoed back in an error a thousand times).
MAX_COUNT = 10**9


class A1(Answer):
    samples_150: Annotated[list[CaseName], Field(max_length=4)]
    samples_75: Annotated[list[CaseName], Field(max_length=4)]
    _unique = field_validator("samples_150", "samples_75")(_unique)


class A2(Answer):
    direction: ProxyChange


class A3(Answer):
    agree: bool


class A4(Answer):
    same_length: bool


class A5(Answer):
    one_number_decides: bool


class B1(Answer):
    lanes: Annotated[list[LaneName], Field(max_length=2)]
    _unique = field_validator("lanes")(_unique)


class B2(Answer):
    lane: LaneName


class B3(Answer):
    lane: Literal["low", "high", "both", "neither"]


class B4(Answer):
    color_layer: Layer
    affects_results: bool


class TimingNumbers(Answer):
    substep_dt: TimeQuantity
    samples: Annotated[int, Field(ge=0, le=MAX_COUNT)]
    internal_updates: Annotated[int, Field(ge=0, le=MAX_COUNT)]


class C2(Answer):
    reason: Literal["unequal_simulated_duration", "unequal_internal_updates", "it_is_valid"]


class C3(Answer):
    reason: Literal["unshared_samples_have_no_counterpart", "different_internal_dt", "not_necessary"]


class C4(Answer):
    proves_rebound: bool


class C5(Answer):
    pair_friction: Annotated[float, Field(ge=0.0, allow_inf_nan=False)]


class C6(Answer):
    pair_rule: Literal["max", "min", "mean", "product"]


class C7(Answer):
    color_effect: Literal["none", "blue_slides_farther", "orange_slides_farther"]


class C8(Answer):
    establishes_stop: bool


class LanePairs(SheetModel):
    low: Annotated[float, Field(ge=0.0, allow_inf_nan=False)]
    high: Annotated[float, Field(ge=0.0, allow_inf_nan=False)]


class H1(Answer):
    baseline: LanePairs
    modified: LanePairs


class H2(Answer):
    low: DistanceChange


class H3(Answer):
    high: DistanceChange


class LaneStops(SheetModel):
    low: StopReport
    high: StopReport


class H4(Answer):
    baseline: LaneStops
    modified: LaneStops


class H5(Answer):
    only_table_friction_changed: bool


class H6(Answer):
    engine_version: Annotated[str, Field(min_length=1, max_length=32)]


class X2(Answer):
    may_improve: Annotated[list[Diagnostic], Field(max_length=7)]
    _unique = field_validator("may_improve")(_unique)


class X3(Answer):
    every_diagnostic_improves: bool
    not_guaranteed: Annotated[list[Diagnostic], Field(max_length=7)] = []


class Answers(SheetModel):
    """One field per lesson question; every one is required (ids are the rubric's item ids)."""

    A1: A1
    A2: A2
    A3: A3
    A4: A4
    A5: A5
    B1: B1
    B2: B2
    B3: B3
    B4: B4
    C1: TimingNumbers
    C2: C2
    C3: C3
    C4: C4
    C5: C5
    C6: C6
    C7: C7
    C8: C8
    H1: H1
    H2: H2
    H3: H3
    H4: H4
    H5: H5
    H6: H6
    X1: TimingNumbers
    X2: X2
    X3: X3


class Configs(SheetModel):
    """The student's own case configs. N1..N4 are optional (the lesson's are used when absent)."""

    N1: ContactCase | None = None
    N2: ContactCase | None = None
    N3: ContactCase | None = None
    N4: ContactCase | None = None
    table_exercise: FrictionCase
    extension: ContactCase

    def submitted(self) -> dict[str, ContactCase | FrictionCase]:
        return {role: spec for role in type(self).model_fields if (spec := getattr(self, role)) is not None}


class PredictionSheet(SheetModel):
    lesson: Literal["L03"]
    student: Annotated[str, Field(min_length=1, max_length=128, pattern=r"^[A-Za-z0-9_.@\-]+$")]
    answers: Answers
    configs: Configs

    def spec_for(self, name: str, cases: Mapping[str, ContactCase | FrictionCase] | None = None
                 ) -> ContactCase | FrictionCase:
        """A role's spec: the student's own when submitted, else the lesson's case of that name (from `cases`, the
        student's variant's case table, when given; rubric.variants.variant_cases)."""
        return self.configs.submitted().get(name) or (BASELINE_CASES if cases is None else cases)[name]

    @model_validator(mode="after")
    def _distinct_case_names(self) -> "PredictionSheet":
        names = [spec.name for spec in self.configs.submitted().values()]
        if len(set(names)) != len(names):
            raise PydanticCustomError("config_names", "configs: case names must be unique, got {n}", {"n": names})
        return self


# The items of the rubric each part of the lesson holds; an assignment asks for the checkpoints, the exercises (every
# other item: predictions, hands-on and extension, which need the student's configs) or the whole sheet.
CHECKPOINT_IDS = ("C1", "C2", "C3", "C4", "C5", "C6", "C7", "C8")
EXERCISE_IDS = tuple(name for name in Answers.model_fields if name not in CHECKPOINT_IDS)


class CheckpointAnswers(SheetModel):
    """The concept checkpoints only: a checkpoint assignment's sheet answers these and nothing else."""

    C1: TimingNumbers
    C2: C2
    C3: C3
    C4: C4
    C5: C5
    C6: C6
    C7: C7
    C8: C8


class ExerciseAnswers(SheetModel):
    """Every item but the checkpoints."""

    A1: A1
    A2: A2
    A3: A3
    A4: A4
    A5: A5
    B1: B1
    B2: B2
    B3: B3
    B4: B4
    H1: H1
    H2: H2
    H3: H3
    H4: H4
    H5: H5
    H6: H6
    X1: TimingNumbers
    X2: X2
    X3: X3


class NoConfigs(SheetModel):
    """A checkpoint sheet submits no config: its items read only the lesson's own cases."""

    def submitted(self) -> dict[str, ContactCase | FrictionCase]:
        return {}


class CheckpointSheet(PredictionSheet):
    answers: CheckpointAnswers
    configs: NoConfigs = NoConfigs()


class ExerciseSheet(PredictionSheet):
    answers: ExerciseAnswers


_SHEETS = {"checkpoints": CheckpointSheet, "exercises": ExerciseSheet, "sheet": PredictionSheet}


def answered(sheet: PredictionSheet) -> tuple[str, ...]:
    """The item ids a sheet answers: all of them, or one assignment's part."""
    return tuple(type(sheet.answers).model_fields)


def parse_sheet(data: Any, part: str = "sheet") -> PredictionSheet:
    """Validate a sheet from JSON/YAML data; raises pydantic.ValidationError naming each bad item and rule.

    `part` (checkpoints | exercises | sheet) says which answers it must hold: exactly those, so an answer to an item
    outside an assignment is refused (named as an extra input) rather than silently graded or dropped.
    """
    return _SHEETS[part].model_validate(data)
