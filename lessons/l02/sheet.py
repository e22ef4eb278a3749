"""The L02 prediction sheet: typed answers to each of its items, and the exercise's config.

Strict as every sheet is (rubric.sheet): unknown items, missing answers and wrong types are errors whose location
names the item (`answers.C2.internal_dt.unit`), never coerced or dropped.
"""

from __future__ import annotations

from typing import Annotated, Any, Literal

from pydantic import Field

from rubric.sheet import MAX_COUNT, Answer, LengthQuantity, SheetModel, TimeQuantity

from .specs import CASES, DropCase

Count = Annotated[int, Field(ge=0, le=MAX_COUNT)]


class Counts(Answer):
    """Samples of each run: one after every outer step."""

    S1: Count
    S2: Count


class Updates(Answer):
    """Internal updates of each run, and S2's internal dt."""

    S1: Count
    S2: Count
    internal_dt: TimeQuantity


class SimulatedTimes(Answer):
    S1: TimeQuantity
    S2: TimeQuantity


class Height(Answer):
    height: LengthQuantity


class Velocity(Answer):
    vz_m_per_s: Annotated[float, Field(ge=-1000.0, le=1000.0, allow_inf_nan=False)]


class TouchTime(Answer):
    time: TimeQuantity


class Lower(Answer):
    lower: Literal["S1", "S2", "same"]


class ExerciseCounts(Answer):
    samples: Count
    internal_updates: Count


class Answers(SheetModel):
    """One field per item of the rubric."""

    C1: Counts
    C2: Updates
    C3: SimulatedTimes
    P1: Height
    P2: Velocity
    P3: TouchTime
    P4: Lower
    E1: ExerciseCounts


class Configs(SheetModel):
    """The exercise's own timing of the drop (only dt and substeps may differ from S1)."""

    exercise: DropCase

    def submitted(self) -> dict[str, DropCase]:
        return {"exercise": self.exercise}


class Sheet(SheetModel):
    lesson: Literal["L02"]
    student: Annotated[str, Field(min_length=1, max_length=128, pattern=r"^[A-Za-z0-9_.@\-]+$")]
    answers: Answers
    configs: Configs

    def spec_for(self, name: str) -> DropCase:
        return self.configs.submitted().get(name) or CASES[name]


CHECKPOINT_IDS = ("C1", "C2", "C3")


class CheckpointAnswers(SheetModel):
    C1: Counts
    C2: Updates
    C3: SimulatedTimes


class ExerciseAnswers(SheetModel):
    P1: Height
    P2: Velocity
    P3: TouchTime
    P4: Lower
    E1: ExerciseCounts


class NoConfigs(SheetModel):
    def submitted(self) -> dict[str, DropCase]:
        return {}


class CheckpointSheet(Sheet):
    answers: CheckpointAnswers
    configs: NoConfigs = NoConfigs()


class ExerciseSheet(Sheet):
    answers: ExerciseAnswers


_SHEETS = {"checkpoints": CheckpointSheet, "exercises": ExerciseSheet, "sheet": Sheet}


def parse_sheet(data: Any, part: str = "sheet") -> Sheet:
    """Validate a sheet; `part` (checkpoints | exercises | sheet) says which answers it must hold, exactly."""
    return _SHEETS[part].model_validate(data)
