"""Variants and the deterministic pool draw: the same space, seed and size give the same pool in any process.

Each draw picks every varying parameter's value from a SHA-256 of (space content hash, seed, attempt, parameter), so
no Python hash randomisation, no global random state and no Python-version-dependent generator is involved. A draw
that breaks a constraint, builds a case the schema refuses, repeats the lesson's published parameters or an earlier
variant is kept in `Pool.rejected` with its reasons; a space that cannot yield the pool within the attempt budget
raises VariantPoolError with those reasons rather than looping for ever.
"""

from __future__ import annotations

import hashlib
import json
import math
from collections import Counter
from collections.abc import Mapping
from typing import Annotated

from pydantic import Field, field_validator
from pydantic_core import PydanticCustomError

from ..rubrics import RubricModel
from .apply import CaseSet, InvalidVariant, complete_parameters, variant_cases
from .parameters import PARAMETERS, shipped_parameters
from .space import VariantSpace

SHIPPED_ID = "shipped"
Number = float | int


class Variant(RubricModel):
    """One lab variant: every lesson parameter's value (the varying ones drawn, the others shipped) and a stable id."""

    id: Annotated[str, Field(pattern=r"^(shipped|v[0-9]+-[0-9]+)$")]
    lesson: str = "L03"
    space_version: str | None = None  # None: the lesson's shipped parameters, no space
    space_hash: str | None = None
    parameters: dict[str, Number]

    @field_validator("parameters")
    @classmethod
    def _typed(cls, parameters: dict[str, Number]) -> dict[str, Number]:
        """Every lesson parameter, each typed as the lesson types it (a stored 800 is density 800.0, substeps stay
        whole), so one variant has one digest however its parameters were written down."""
        unknown = sorted(set(parameters) - set(PARAMETERS))
        missing = sorted(set(PARAMETERS) - set(parameters))
        if unknown or missing:
            raise PydanticCustomError("variant_parameters", "unknown parameters {unknown}, missing {missing}",
                                      {"unknown": unknown, "missing": missing})
        typed = {}
        for name, knob in PARAMETERS.items():
            value = parameters[name]
            if knob.kind == "int":
                if float(value) != int(value):
                    raise PydanticCustomError("whole_number", "{name} takes whole numbers, got {value}",
                                              {"name": name, "value": value})
                typed[name] = int(value)
            else:
                typed[name] = float(value)
        return typed

    @property
    def digest(self) -> str:
        """A short hash of the parameters alone: equal for two variants that would run identical cases."""
        return parameters_digest(self.parameters)

    @property
    def shipped(self) -> bool:
        return self.parameters == shipped_parameters()

    def cases(self) -> CaseSet:
        return variant_cases(self.parameters)


def parameters_digest(parameters: Mapping[str, Number]) -> str:
    canonical = json.dumps(complete_parameters(parameters), sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(canonical.encode()).hexdigest()[:12]


def shipped_variant(lesson: str = "L03") -> Variant:
    """The lesson as it ships: what a free submission, or an assignment without a pool, is graded on."""
    return Variant(id=SHIPPED_ID, lesson=lesson, parameters=shipped_parameters())


class RejectedDraw(RubricModel):
    attempt: int
    parameters: dict[str, Number]  # the drawn values of the varying parameters only
    reasons: list[str]


class Pool(RubricModel):
    lesson: str
    space_version: str
    space_hash: str
    seed: int
    k: int
    variants: list[Variant]
    rejected: list[RejectedDraw]

    def reasons(self) -> dict[str, int]:
        """How often each reason rejected a draw (a constraint's name, 'invalid case', 'shipped', 'repeat')."""
        return dict(Counter(reason.split(":")[0] for r in self.rejected for reason in r.reasons))


class VariantPoolError(ValueError):
    """The space cannot yield the pool asked for: too few combinations, or too many draws refused."""

    def __init__(self, message: str, pool: Pool):
        super().__init__(message)
        self.pool = pool


def _pick(space_hash: str, seed: int, attempt: int, name: str, n: int) -> int:
    digest = hashlib.sha256(f"{space_hash}|{seed}|{attempt}|{name}".encode()).digest()
    return int.from_bytes(digest[:8], "big") % n


def _differences(a: Mapping[str, Number], b: Mapping[str, Number]) -> int:
    return sum(1 for name in a if a[name] != b[name])


def draw_pool(space: VariantSpace, seed: int, k: int = 16, *, min_differences: int = 1,
              max_attempts: int | None = None) -> Pool:
    """K variants of `space` drawn from `seed`: ids v<seed>-1 .. v<seed>-K, each satisfying every constraint, building
    valid cases, and differing from the shipped parameters and from each other in at least `min_differences`
    parameters. The first K of a larger pool from the same seed are this pool (draws are sequential).

    Raises VariantPoolError (its `.pool` holds what was drawn and every rejection) when the space holds fewer
    combinations than asked for, or `max_attempts` draws (default 50 per variant, at least 500) do not yield K."""
    if k < 1 or seed < 0 or min_differences < 1:
        raise ValueError(f"k ({k}) and min_differences ({min_differences}) must be at least 1, seed ({seed}) >= 0")
    choices = space.choices()
    names = sorted(choices)
    space_hash = space.content_hash
    shipped = shipped_parameters()
    variants: list[Variant] = []
    rejected: list[RejectedDraw] = []

    def pool() -> Pool:
        return Pool(lesson=space.lesson, space_version=space.version, space_hash=space_hash, seed=seed, k=k,
                    variants=variants, rejected=rejected)

    combinations = math.prod(len(v) for v in choices.values())
    if combinations < k:
        raise VariantPoolError(f"the variant space {space.lesson} v{space.version} holds {combinations} combinations "
                               f"of its parameters, fewer than the {k} variants asked for", pool())
    budget = max_attempts if max_attempts is not None else max(500, 50 * k)
    for attempt in range(budget):
        if len(variants) == k:
            break
        drawn = {name: choices[name][_pick(space_hash, seed, attempt, name, len(choices[name]))] for name in names}
        full = complete_parameters(drawn)
        reasons = space.violations(drawn)
        if not reasons:
            try:
                variant_cases(full)
            except InvalidVariant as exc:
                reasons += [f"invalid case: {p}" for p in exc.problems]
        if _differences(full, shipped) < min_differences:
            reasons.append("shipped: the lesson's own parameters, whose answers are published, or too close to them "
                           f"(fewer than {min_differences} parameters differ)")
        close = next((v for v in variants if _differences(full, v.parameters) < min_differences), None)
        if close is not None:
            reasons.append(f"repeat: fewer than {min_differences} parameters differ from {close.id}")
        if reasons:
            rejected.append(RejectedDraw(attempt=attempt, parameters=drawn, reasons=reasons))
            continue
        variants.append(Variant(id=f"v{seed}-{len(variants) + 1}", lesson=space.lesson,
                                     space_version=space.version, space_hash=space_hash, parameters=full))
    if len(variants) < k:
        top = ", ".join(f"{reason} x{n}" for reason, n in Counter(pool().reasons()).most_common(5))
        raise VariantPoolError(f"only {len(variants)} of {k} variants after {budget} draws; draws were refused "
                               f"by {top}", pool())
    return pool()
