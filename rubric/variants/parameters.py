"""The L03 parameters a variant may move, and the lesson's shipped value of each, read from the baseline case table.

A variant space (space.py) chooses values for some of these; every other one stays at its shipped value. The shipped
values are read from rubric.cases, never restated here, so a variant with every parameter at its shipped value builds
exactly the lesson's cases (apply.py, tested).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from ..cases import BASELINE_CASES


@dataclass(frozen=True)
class Knob:
    """One parameter of the lesson: what it is, its unit and type, the values the engine and the case schema accept."""

    unit: str
    kind: Literal["float", "int"]
    low: float
    high: float
    description: str


_FRICTION = (0.01, 5.0)  # Genesis 1.3.3 rejects a Rigid material friction outside [0.01, 5.0] (rubric.specs.Friction)

PARAMETERS: dict[str, Knob] = {
    # Part A: the contact experiment (N1-N4 and the extension N5).
    "cube_start_z": Knob("m", "float", 0.0, 100.0, "centre height at which the contact cube starts (drop height)"),
    "cube_size": Knob("m", "float", 0.01, 0.2, "cube edge, the same in both experiments"),
    "cube_rho": Knob("kg/m^3", "float", 1.0, 50_000.0, "cube density, the same in both experiments"),
    "duration": Knob("s", "float", 0.1, 30.0, "simulated duration of every contact case"),
    "fine_dt": Knob("s", "float", 1e-4, 0.1, "outer dt of N1 and N2"),
    "coarse_dt": Knob("s", "float", 1e-4, 0.1, "outer dt of N3 and N4"),
    "base_substeps": Knob("substeps", "int", 1, 64, "substeps of N1 and N3"),
    "more_substeps": Knob("substeps", "int", 1, 64, "substeps of N2 and N4"),
    "extension_dt": Knob("s", "float", 1e-4, 0.1, "outer dt of the extension's fifth contact case"),
    "extension_substeps": Knob("substeps", "int", 1, 64, "substeps of the extension's fifth contact case"),
    # Part B: friction and stopping distance (baseline, the hands-on exercise, the colour control).
    "table_friction": Knob("1", "float", *_FRICTION, "table friction of the baseline friction run"),
    "exercise_table_friction": Knob("1", "float", *_FRICTION, "table friction of the hands-on exercise"),
    "low_lane_friction": Knob("1", "float", *_FRICTION, "cube friction of the low-friction lane"),
    "high_lane_friction": Knob("1", "float", *_FRICTION, "cube friction of the high-friction lane"),
    "launch_speed": Knob("m/s", "float", 0.1, 20.0, "horizontal speed both lanes get at measurement time zero"),
}


def _lane(name: str, lane: str) -> float:
    return next(x.friction for x in BASELINE_CASES[name].lanes if x.name == lane)


def shipped_parameters() -> dict[str, float | int]:
    """Every parameter at the value the lesson ships (the baseline case table), by name."""
    n1, n2, n3, n5 = (BASELINE_CASES[n] for n in ("N1", "N2", "N3", "N5"))
    base, exercise = BASELINE_CASES["friction-baseline"], BASELINE_CASES["friction-table-0.30"]
    values = {
        "cube_start_z": n1.cube.pos[2], "cube_size": n1.cube.size, "cube_rho": n1.cube.rho,
        "duration": n1.duration, "fine_dt": n1.dt, "coarse_dt": n3.dt,
        "base_substeps": n1.substeps, "more_substeps": n2.substeps,
        "extension_dt": n5.dt, "extension_substeps": n5.substeps,
        "table_friction": base.table.friction, "exercise_table_friction": exercise.table.friction,
        "low_lane_friction": _lane("friction-baseline", "low"), "high_lane_friction": _lane("friction-baseline", "high"),
        "launch_speed": base.initial_speed,
    }
    assert set(values) == set(PARAMETERS), "every registered parameter has a shipped value"
    return values


def fixed_quantities() -> dict[str, float]:
    """Quantities of the lesson no variant moves, by the names a constraint rule may read."""
    n1, base = BASELINE_CASES["N1"], BASELINE_CASES["friction-baseline"]
    return {
        "table_top_z": n1.table.top_z,  # the contact table's top face
        "g": -n1.gravity[2],
        "friction_duration": base.duration,  # measurement window of the friction runs
        "hold": base.hold,  # the sustained-stop hold interval
        # Room a lane has to slide: from its start to the far end of the friction table.
        "lane_room": base.table.pos[0] + base.table.size[0] / 2 - base.start_x,
    }

