"""L03 case specifications: what a student or the lesson may ask the engine to run, and the rules it must obey.

Only independent inputs are fields. Quantities the lesson derives (substep_dt, n_steps, internal updates,
sample count, resting height) are computed properties, so a spec can never contradict itself.
"""

from __future__ import annotations

import functools
import json
import math
import struct
import re
from typing import Annotated, Any, Literal, Union

from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    ValidationInfo,
    computed_field,
    field_validator,
    model_validator,
)
from pydantic_core import PydanticCustomError

# Caps that keep one case within what a worker slot can run in minutes, not hours.
MAX_N_STEPS = 20_000
MAX_INTERNAL_UPDATES = 200_000
MAX_DURATION_S = 30.0
MAX_SIZE_M = 10.0
MAX_SUBSTEPS = 64
# duration / dt may differ from an integer only by float representation error (e.g. 1.5 / 0.01).
STEP_COUNT_REL_TOL = 1e-9

Backend = Literal["cpu", "rocm", "cuda"]
Precision = Literal["32", "64"]


Length = Annotated[float, Field(gt=0.0, le=MAX_SIZE_M)]
Coordinate = Annotated[float, Field(ge=-100.0, le=100.0)]
# Genesis 1.3.3 rejects a Rigid material friction outside [0.01, 5.0] (genesis/engine/materials/rigid.py).
Friction = Annotated[float, Field(ge=0.01, le=5.0)]
Density = Annotated[float, Field(gt=0.0, le=50_000.0)]
Unit = Annotated[float, Field(ge=0.0, le=1.0)]
Vec3 = tuple[Coordinate, Coordinate, Coordinate]
Size3 = tuple[Length, Length, Length]
Color = tuple[Unit, Unit, Unit]


class StrictModel(BaseModel):
    """Unknown fields are an error, never silently dropped: a misspelt 'substep' must not run as the default."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


class Table(StrictModel):
    """The fixed table: a Box whose top face is the contact surface."""

    size: Size3 = (0.9, 0.6, 0.05)
    pos: Vec3 = (0.35, 0.0, 0.70)
    friction: Friction = 0.8

    @computed_field
    @property
    def top_z(self) -> float:
        return self.pos[2] + self.size[2] / 2


class Cube(StrictModel):
    """The falling cube of the contact experiment (edge length `size`)."""

    size: Length = 0.08
    pos: Vec3 = (0.35, 0.0, 1.0)
    rho: Density = 500.0
    friction: Friction = 0.5
    color: Color = (1.0, 0.5, 0.0)


class Timing(StrictModel):
    """Numerical layer shared by both experiments: dt and substeps in, everything else derived."""

    dt: Annotated[float, Field(gt=0.0, le=0.1)]
    substeps: Annotated[int, Field(ge=1, le=MAX_SUBSTEPS, strict=True)]
    duration: Annotated[float, Field(gt=0.0, le=MAX_DURATION_S)]

    @field_validator("duration")
    @classmethod
    def _integral_step_count(cls, duration: float, info: ValidationInfo) -> float:
        dt, substeps = info.data.get("dt"), info.data.get("substeps")
        if dt is None:
            return duration  # dt's own error is already reported
        ratio = duration / dt
        if abs(ratio - round(ratio)) > STEP_COUNT_REL_TOL * max(1.0, ratio):
            raise PydanticCustomError(
                "integral_step_count",
                "duration / dt = {ratio} is not an integer number of outer steps "
                "(cases are compared over equal simulated duration)",
                {"ratio": ratio},
            )
        n_steps = round(ratio)
        if n_steps > MAX_N_STEPS:
            raise PydanticCustomError(
                "step_cap", "duration / dt = {n} outer steps exceeds the cap of {cap}", {"n": n_steps, "cap": MAX_N_STEPS}
            )
        if substeps is not None and n_steps * substeps > MAX_INTERNAL_UPDATES:
            raise PydanticCustomError(
                "update_cap",
                "n_steps x substeps = {n} internal updates exceeds the cap of {cap}",
                {"n": n_steps * substeps, "cap": MAX_INTERNAL_UPDATES},
            )
        return duration

    @computed_field
    @property
    def substep_dt(self) -> float:
        return self.dt / self.substeps

    @computed_field
    @property
    def n_steps(self) -> int:
        return round(self.duration / self.dt)

    @computed_field
    @property
    def internal_updates(self) -> int:
        return self.n_steps * self.substeps


class Execution(StrictModel):
    """Where and how a case runs; none of it is physics, all of it is provenance."""

    seed: Annotated[int, Field(ge=0, le=2**31 - 1, strict=True)] = 0
    precision: Precision = "32"
    backend: Backend = "cpu"
    render: bool = False


class ContactCase(Timing, Execution):
    """Part A: one cube dropped on a fixed table; only dt and substeps vary between the lesson's cases."""

    kind: Literal["contact"] = "contact"
    name: Annotated[str, Field(min_length=1, max_length=64, pattern=r"^[A-Za-z0-9_.\-]+$")]
    dt: Annotated[float, Field(gt=0.0, le=0.1)] = 0.01
    substeps: Annotated[int, Field(ge=1, le=MAX_SUBSTEPS, strict=True)] = 1
    # validate_default: the step-count rule must hold for the default duration too (dt=0.013 with 1.5 s is not integral).
    duration: Annotated[float, Field(gt=0.0, le=MAX_DURATION_S, validate_default=True)] = 1.5
    gravity: Vec3 = (0.0, 0.0, -9.81)
    enable_collision: bool = True
    table: Table = Table()
    cube: Cube = Cube()
    # Observation rules, declared before running.
    separation_tolerance: Annotated[float, Field(ge=0.0, le=0.1)] = 0.001
    upward_speed_tolerance: Annotated[float, Field(ge=0.0, le=10.0)] = 0.05
    tail_window: Annotated[float, Field(gt=0.0, le=MAX_DURATION_S)] = 0.25

    @model_validator(mode="after")
    def _cube_starts_outside_table(self) -> "ContactCase":
        overlap = _box_overlap(self.table, self.cube.pos, (self.cube.size,) * 3)
        if overlap:
            raise PydanticCustomError(
                "cube_inside_table",
                "cube.pos: the cube starts inside the table (overlap {overlap} m); its bottom must be at or above "
                "the table top z={top} m",
                {"overlap": f"{overlap:.4f}", "top": f"{self.table.top_z:.4f}"},
            )
        if self.tail_window > self.duration:
            raise PydanticCustomError(
                "tail_window", "tail_window: {w} s is longer than duration {d} s", {"w": self.tail_window, "d": self.duration}
            )
        return self

    @computed_field
    @property
    def sample_count(self) -> int:
        """One sample after every outer step."""
        return self.n_steps

    @computed_field
    @property
    def expected_center_z(self) -> float:
        """Ideal resting centre height of the aligned cube on the table top."""
        return self.table.top_z + self.cube.size / 2


class Lane(StrictModel):
    """One sliding cube of Part B. Its color is visual only: it must never enter the physics."""

    name: Annotated[str, Field(min_length=1, max_length=16, pattern=r"^[a-z][a-z0-9_]*$")]
    friction: Friction
    y: Coordinate
    color: Color


class FrictionCase(Timing, Execution):
    """Part B: equal cubes slide on one table after a settling interval; only cube-side friction differs."""

    kind: Literal["friction"] = "friction"
    name: Annotated[str, Field(min_length=1, max_length=64, pattern=r"^[A-Za-z0-9_.\-]+$")]
    dt: Annotated[float, Field(gt=0.0, le=0.1)] = 0.01
    substeps: Annotated[int, Field(ge=1, le=MAX_SUBSTEPS, strict=True)] = 2
    # Measurement duration, counted from measurement time zero (after settling).
    duration: Annotated[float, Field(gt=0.0, le=MAX_DURATION_S, validate_default=True)] = 2.0
    gravity: Vec3 = (0.0, 0.0, -9.81)
    enable_collision: bool = True
    # Long enough that the low-effective-friction lane (slid ~0.7 m at table 0.30) stays on it.
    table: Table = Table(size=(2.0, 0.6, 0.05), pos=(0.8, 0.0, 0.70), friction=0.5)
    cube_size: Length = 0.08
    cube_rho: Density = 500.0
    start_x: Coordinate = 0.0
    lanes: Annotated[list[Lane], Field(min_length=1, max_length=4)] = [
        Lane(name="low", friction=0.10, y=-0.15, color=(1.0, 0.5, 0.0)),
        Lane(name="high", friction=0.80, y=0.15, color=(0.1, 0.3, 1.0)),
    ]
    settle_steps: Annotated[int, Field(ge=0, le=1_000, strict=True)] = 20
    initial_speed: Annotated[float, Field(ge=0.0, le=20.0)] = 2.0
    # Sustained-stop rule, declared before running.
    stop_speed: Annotated[float, Field(gt=0.0, le=1.0)] = 0.01
    hold: Annotated[float, Field(gt=0.0, le=MAX_DURATION_S)] = 0.2

    @model_validator(mode="after")
    def _lanes_fit(self) -> "FrictionCase":
        names = [lane.name for lane in self.lanes]
        if len(set(names)) != len(names):
            raise PydanticCustomError("lane_names", "lanes: lane names must be unique, got {names}", {"names": names})
        half = self.cube_size / 2
        tx, ty, _ = self.table.pos
        sx, sy, _ = self.table.size
        for i, lane in enumerate(self.lanes):
            on_x = tx - sx / 2 <= self.start_x - half and self.start_x + half <= tx + sx / 2
            on_y = ty - sy / 2 <= lane.y - half and lane.y + half <= ty + sy / 2
            if not (on_x and on_y):
                raise PydanticCustomError(
                    "lane_off_table",
                    "lanes.{i}: cube '{name}' at x={x}, y={y} does not start fully on the table",
                    {"i": i, "name": lane.name, "x": self.start_x, "y": lane.y},
                )
        ys = sorted(lane.y for lane in self.lanes)
        if any(b - a < self.cube_size * 1.5 for a, b in zip(ys, ys[1:])):
            raise PydanticCustomError(
                "lanes_too_close", "lanes: lane y positions must be at least 1.5 cube sizes apart, got {ys}", {"ys": ys}
            )
        return self

    @computed_field
    @property
    def rest_z(self) -> float:
        """Cubes start at their geometric resting height (centre), derived from the table top."""
        return self.table.top_z + self.cube_size / 2

    @computed_field
    @property
    def sample_count(self) -> int:
        """One sample at measurement time zero plus one after every outer step."""
        return self.n_steps + 1

    @computed_field
    @property
    def hold_steps(self) -> int:
        """Outer steps spanned by the hold interval (the stop rule needs hold_steps + 1 samples below threshold)."""
        return math.ceil(self.hold / self.dt - STEP_COUNT_REL_TOL)


def _box_overlap(table: Table, pos: tuple[float, float, float], size: tuple[float, float, float]) -> float:
    """Smallest axis overlap of two axis-aligned boxes, 0 when they do not intersect."""
    overlaps = []
    for axis in range(3):
        lo = max(table.pos[axis] - table.size[axis] / 2, pos[axis] - size[axis] / 2)
        hi = min(table.pos[axis] + table.size[axis] / 2, pos[axis] + size[axis] / 2)
        overlaps.append(hi - lo)
    smallest = min(overlaps)
    return smallest if smallest > 1e-12 else 0.0


CaseSpec = Annotated[Union[ContactCase, FrictionCase], Field(discriminator="kind")]


@functools.cache
def _case_adapter():
    """Built once per process: a TypeAdapter builds its validator from the type each time (about 6 ms here), and a
    grade parses each of its runs' specs (issue 35: a class's 200 grades and lab checks spent seconds of CPU on it)."""
    from pydantic import TypeAdapter

    return TypeAdapter(CaseSpec)


def parse_case(data: dict) -> ContactCase | FrictionCase:
    """Validate a case spec from JSON-like data; raises pydantic.ValidationError naming each bad field. A kind another
    installed lesson declares is validated by its model (rubric.lesson.parse_spec); any other by L03's."""
    kind = data.get("kind") if isinstance(data, dict) else None
    if isinstance(kind, str) and kind not in ("contact", "friction"):
        from .lesson import LessonNotFound, parse_spec

        try:
            return parse_spec(data)
        except LessonNotFound:
            pass  # no lesson declares it: L03's union says which kinds it takes
    return _case_adapter().validate_python(data)


def describe_errors(error) -> list[str]:
    """One line per problem, 'field.path: rule', for CLI output and API error bodies."""
    lines = []
    for item in error.errors(include_url=False):
        loc = list(item["loc"])
        if loc and loc[0] in ("contact", "friction"):  # the union's discriminator tag, not a field
            loc = loc[1:]
        loc = ".".join(str(part) for part in loc)
        msg = item["msg"]
        lines.append(f"{loc}: {msg}" if loc else msg)
    return lines


# Not compared by the one-factor rule: a case's label, and whether a camera watched it (evidence, not physics).
IGNORED_FIELDS = {"name", "render"}
# The visual layer: Surface colours identify objects in plots and frames and are never engine inputs of the physics.
VISUAL_FIELD = re.compile(r"^(cube\.color|lanes\.[0-9]+\.color)$")


class FieldChange(BaseModel):
    field: str
    baseline: Any
    config: Any

    @property
    def visual(self) -> bool:
        """A change of the visual layer only (a colour): it cannot confound a physical comparison."""
        return VISUAL_FIELD.match(self.field) is not None


def _flatten(value: Any, prefix: str = "") -> dict[str, Any]:
    if isinstance(value, dict):
        out = {}
        for key, item in value.items():
            out |= _flatten(item, f"{prefix}{key}.")
        return out
    if isinstance(value, list) and value and isinstance(value[0], dict):
        out = {}
        for i, item in enumerate(value):
            out |= _flatten(item, f"{prefix}{i}.")
        return out
    return {prefix[:-1]: value}


def field_changes(baseline: ContactCase | FrictionCase, config: ContactCase | FrictionCase) -> list[FieldChange]:
    """Every input field whose value differs (dotted paths like `table.friction`, `lanes.0.friction`)."""
    a = _flatten(baseline.model_dump(mode="json", exclude_computed_fields=True))
    b = _flatten(config.model_dump(mode="json", exclude_computed_fields=True))
    return [
        FieldChange(field=key, baseline=a.get(key), config=b.get(key))
        for key in sorted(set(a) | set(b))
        if key not in IGNORED_FIELDS and a.get(key) != b.get(key)
    ]


# What a case's arrays do not depend on: its label and where or how it ran (a 64-bit or GPU run measures the same
# physics to within drift), its colours (the visual layer), and the analysis thresholds read from the arrays after the
# run. Its sampling is replaced by what the engine integrates: dt and substeps by the internal step substep_dt (N1 and
# N4 agree at every shared sample), the duration dropped (a shorter run is a prefix of a longer one), a friction
# case's settle_steps by the internal updates of its settling.
_LANE_NAME = re.compile(r"^lanes\.[0-9]+\.name$")  # a lane's label
_NOT_PHYSICS = {"name", "render", "backend", "precision", "seed", "dt", "substeps", "duration",
                "separation_tolerance", "upward_speed_tolerance", "tail_window", "stop_speed", "hold", "settle_steps"}


def _single(value: Any) -> Any:
    """A float as single precision holds it (the engine's 32-bit fields: 0.5000000001 is 0.5 there), other values as
    they are. A 64-bit run is then grouped with runs a little apart from it: more is withheld, never less."""
    if isinstance(value, float):
        try:
            return float(struct.unpack("f", struct.pack("f", value))[0])
        except OverflowError:  # past single precision's range: no 32-bit field holds it, kept as it is
            return value
    if isinstance(value, list):
        return [_single(v) for v in value]
    return value


def physics_key(spec: ContactCase | FrictionCase) -> str:
    """The physics a case integrates, however it is sampled, labelled or run: two cases with one key measure the same
    trajectories at every shared time, as the colour-swapped control measures the baseline bit for bit and an
    extension at dt 0.02 with 4 substeps measures N2 (dt 0.01, 2 substeps) at every other sample. What the service
    withholds with a withheld run is every run of the same physics (grader.services.submissions.visibility)."""
    fields = {k: _single(v) for k, v in _flatten(spec.model_dump(mode="json", exclude_computed_fields=True)).items()
              if k not in _NOT_PHYSICS and not VISUAL_FIELD.match(k) and not _LANE_NAME.match(k)}
    fields["substep_dt"] = _single(_single(spec.dt) / spec.substeps)
    if isinstance(spec, FrictionCase):
        fields["settle_updates"] = spec.settle_steps * spec.substeps
    return json.dumps(fields, sort_keys=True, separators=(",", ":"))
