"""A variant's parameters applied to the lesson's case table: the same case names, the same spec types, the worker runs
them unchanged. Pure: every spec is validated by the case schema (rubric.specs) as the lesson's own are.
"""

from __future__ import annotations

from collections.abc import Mapping

from ..cases import BASELINE_CASES, COLOR_SWAP
from pydantic import ValidationError

from ..specs import ContactCase, FrictionCase, describe_errors
from .parameters import PARAMETERS, shipped_parameters

CaseSet = dict[str, ContactCase | FrictionCase]


class InvalidVariant(ValueError):
    """Parameters that build a case the case schema refuses; `problems` names each case and field ('N3.duration: ...')."""

    def __init__(self, problems: list[str]):
        super().__init__("; ".join(problems))
        self.problems = problems


def complete_parameters(parameters: Mapping[str, float | int] | None) -> dict[str, float | int]:
    """`parameters` over the shipped values; an unknown name is an error naming it, never silently ignored."""
    unknown = sorted(set(parameters or {}) - set(PARAMETERS))
    if unknown:
        raise KeyError(f"unknown variant parameters {unknown}; known: {', '.join(PARAMETERS)}")
    return shipped_parameters() | dict(parameters or {})


def _rebuilt(case, **update):
    """`case` with fields replaced, validated again (a dump through the schema, so every rule of specs.py runs)."""
    data = case.model_dump(exclude_computed_fields=True)
    name = update.get("name", case.name)
    for path, value in update.items():
        node = data
        *parents, leaf = path.split("__")
        for key in parents:
            node = node[key]
        node[leaf] = value
    try:
        return type(case).model_validate(data)
    except ValidationError as exc:
        raise InvalidVariant([f"{name}.{line}" for line in describe_errors(exc)]) from None


def variant_cases(parameters: Mapping[str, float | int] | None = None) -> CaseSet:
    """Every lesson case (N1-N5, the friction baseline, its table exercise and its colour swap) under `parameters`
    (a Variant's, or a partial mapping over the shipped values; None: the lesson's own table, the same objects).

    Raises InvalidVariant naming the case and field when a value is one the case schema refuses."""
    if parameters is None:
        return dict(BASELINE_CASES)
    p = complete_parameters(parameters)
    timing = {
        "N1": (p["fine_dt"], p["base_substeps"]),
        "N2": (p["fine_dt"], p["more_substeps"]),
        "N3": (p["coarse_dt"], p["base_substeps"]),
        "N4": (p["coarse_dt"], p["more_substeps"]),
        "N5": (p["extension_dt"], p["extension_substeps"]),
    }
    cases: CaseSet = {}
    for name, (dt, substeps) in timing.items():
        shipped = BASELINE_CASES[name]
        x, y, _ = shipped.cube.pos
        cases[name] = _rebuilt(shipped, dt=dt, substeps=substeps, duration=p["duration"], cube__size=p["cube_size"],
                               cube__rho=p["cube_rho"], cube__pos=(x, y, p["cube_start_z"]))
    frictions = {"low": p["low_lane_friction"], "high": p["high_lane_friction"]}
    shipped = BASELINE_CASES["friction-baseline"]
    lanes = [lane.model_copy(update={"friction": frictions[lane.name]}).model_dump() for lane in shipped.lanes]
    base = _rebuilt(shipped, table__friction=p["table_friction"], cube_size=p["cube_size"], cube_rho=p["cube_rho"],
                    initial_speed=p["launch_speed"], lanes=lanes)
    cases["friction-baseline"] = base
    # The hands-on exercise and the colour control are defined from the baseline exactly as rubric.cases defines them.
    cases["friction-table-0.30"] = _rebuilt(base, name="friction-table-0.30",
                                            table__friction=p["exercise_table_friction"])
    swapped = [lane.model_copy(update={"color": other.color}).model_dump()
               for lane, other in zip(base.lanes, base.lanes[::-1])]
    cases[COLOR_SWAP] = _rebuilt(base, name=COLOR_SWAP, lanes=swapped)
    assert list(cases) == list(BASELINE_CASES), "a variant has exactly the lesson's cases, in its order"
    return cases
