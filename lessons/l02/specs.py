"""L02's one case kind: a Box dropped onto the ground plane, the physics held fixed, only the timing chosen.

The lesson keeps the physics configuration fixed so that the lifecycle is the only subject under test: the box's size,
density, start height and gravity are constants of the lesson, not fields a config could change. A case chooses dt,
substeps and the simulated duration (rubric.specs.Timing: the derived quantities are computed, never given) and where
it runs (rubric.specs.Execution).
"""

from __future__ import annotations

import math
from typing import Annotated, Literal

from pydantic import Field, computed_field, model_validator
from pydantic_core import PydanticCustomError

from rubric.specs import MAX_DURATION_S, MAX_SUBSTEPS, Execution, StrictModel, Timing

# The physics, held fixed by the lesson.
BOX_SIZE_M = 0.1
BOX_START_Z_M = 1.0  # the box's centre; its bottom face starts 0.95 m above the ground
BOX_RHO = 500.0
GRAVITY = 9.81
# The time the lesson asks about (the box is in free fall then), and the shortest run that sees it touch down.
QUERY_T_S = 0.3
MIN_DURATION_S = 0.5
# A sample time equals QUERY_T_S when duration-style arithmetic says so (float representation of 0.3 / dt).
_INTEGRAL_TOL = 1e-9


class DropCase(Timing, Execution, StrictModel):
    """One Box dropped onto the ground; one sample of its state after every outer step."""

    kind: Literal["drop"] = "drop"
    name: Annotated[str, Field(min_length=1, max_length=64, pattern=r"^[A-Za-z0-9_.\-]+$")]
    dt: Annotated[float, Field(gt=0.0, le=0.1)] = 0.01
    substeps: Annotated[int, Field(ge=1, le=MAX_SUBSTEPS, strict=True)] = 1
    duration: Annotated[float, Field(ge=MIN_DURATION_S, le=MAX_DURATION_S, validate_default=True)] = 0.6

    @model_validator(mode="after")
    def _samples_the_query_time(self) -> "DropCase":
        ratio = QUERY_T_S / self.dt
        if abs(ratio - round(ratio)) > _INTEGRAL_TOL * max(1.0, ratio):
            raise PydanticCustomError(
                "query_time", "dt: {dt} s does not divide {q} s, so no sample is taken at t = {q} s (the lesson's "
                "question time)", {"dt": self.dt, "q": QUERY_T_S})
        return self

    @computed_field
    @property
    def sample_count(self) -> int:
        """One sample after every outer step."""
        return self.n_steps

    @property
    def query_index(self) -> int:
        """The sample taken at t = QUERY_T_S (samples are taken after each step: sample i is at (i + 1) dt)."""
        return round(QUERY_T_S / self.dt) - 1


def free_fall(t: float) -> tuple[float, float]:
    """The box's centre height and vertical velocity at time t before it touches the ground, by the exact solution
    z = z0 - g t^2 / 2, vz = -g t (what a student can compute on paper)."""
    return BOX_START_Z_M - GRAVITY * t * t / 2, -GRAVITY * t


def touch_time() -> float:
    """When the box's bottom face reaches the ground in exact free fall."""
    return math.sqrt(2 * (BOX_START_Z_M - BOX_SIZE_M / 2) / GRAVITY)


# The lesson's two runs: the same drop over the same simulated duration at two timing settings.
CASES = {
    "S1": DropCase(name="S1", dt=0.01, substeps=1),
    "S2": DropCase(name="S2", dt=0.005, substeps=2),
}
