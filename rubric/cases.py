"""The lesson's baseline case table, defined once: every other module asks here for N1..N4 and the friction runs."""

from __future__ import annotations

from .specs import ContactCase, FrictionCase, Table

# Part A: the 2x2 contact experiment. Only dt and substeps vary; N5 is the lesson's extension case.
_CONTACT = {
    "N1": (0.01, 1),
    "N2": (0.01, 2),
    "N3": (0.02, 1),
    "N4": (0.02, 2),
    "N5": (0.01, 4),
}

COLOR_SWAP = "friction-baseline-colors-swapped"

BASELINE_CASES: dict[str, ContactCase | FrictionCase] = {
    name: ContactCase(name=name, dt=dt, substeps=substeps) for name, (dt, substeps) in _CONTACT.items()
}
BASELINE_CASES["friction-baseline"] = FrictionCase(name="friction-baseline")
# The hands-on exercise: only table friction changes, 0.50 -> 0.30.
BASELINE_CASES["friction-table-0.30"] = FrictionCase(
    name="friction-table-0.30",
    table=BASELINE_CASES["friction-baseline"].table.model_copy(update={"friction": 0.30}),
)

# The colour control: the baseline with the two lanes' Surface colours swapped. Colour is visual, so grading expects
# the same physics; the run measures it instead of asserting it.
_baseline = BASELINE_CASES["friction-baseline"]
BASELINE_CASES[COLOR_SWAP] = FrictionCase(
    name=COLOR_SWAP,
    lanes=[lane.model_copy(update={"color": other.color}) for lane, other in zip(_baseline.lanes, _baseline.lanes[::-1])],
)

CONTACT_CASES = ("N1", "N2", "N3", "N4")
FRICTION_CASES = ("friction-baseline", "friction-table-0.30")
# What `grader check` runs: the lesson's "How to know the lab worked" needs exactly these.
CHECK_CASES = CONTACT_CASES + FRICTION_CASES


def get_case(name: str) -> ContactCase | FrictionCase:
    """A baseline case by its lesson name; KeyError lists the known names."""
    try:
        return BASELINE_CASES[name]
    except KeyError:
        raise KeyError(f"unknown case {name!r}; known cases: {', '.join(BASELINE_CASES)}") from None


def with_backend(case, *, backend: str, render: bool | None = None):
    """The same case on another backend (and render mode); physics and observation rules unchanged."""
    update = {"backend": backend}
    if render is not None:
        update["render"] = render
    return type(case).model_validate({**case.model_dump(exclude_computed_fields=True), **update})


__all__ = ["BASELINE_CASES", "CHECK_CASES", "COLOR_SWAP", "CONTACT_CASES", "FRICTION_CASES", "Table", "get_case", "with_backend"]
