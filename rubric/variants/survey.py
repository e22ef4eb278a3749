"""What measuring a sample of a variant space says about it (issue 47): the kept fraction, the drops by lab condition,
kept and dropped per parameter value and per contact case's internal step, and the constraints that would have removed
the drops without losing a kept variant. Pure: the measured outcomes come in (tools.variant_space runs them).

A proposal is only a proposal: a reviewer publishes it as a constraint of a new space version, with a rationale
(rubric.governance.publish_variant_space), and the new space is measured again.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Iterable, Mapping

from ..rubrics import RubricModel

Number = float | int

# The internal step (outer dt / substeps) of each contact case: what the lesson's timing relations are about, and where
# a drop pattern may show when no single parameter does (N1's step decides substeps_reduce_proxy, issue 47).
STEPS = {
    "N1_internal_dt": ("fine_dt", "base_substeps"),
    "N2_internal_dt": ("fine_dt", "more_substeps"),
    "N3_internal_dt": ("coarse_dt", "base_substeps"),
    "N4_internal_dt": ("coarse_dt", "more_substeps"),
    "N5_internal_dt": ("extension_dt", "extension_substeps"),
}


class Outcome(RubricModel):
    """One measured variant: its parameters (all of them), whether its lab check passed, the conditions it failed."""

    id: str
    parameters: dict[str, Number]
    kept: bool
    failed: list[str] = []
    seconds: float | None = None


class Tally(RubricModel):
    kept: int = 0
    dropped: int = 0

    @property
    def measured(self) -> int:
        return self.kept + self.dropped


class Proposal(RubricModel):
    """A rule that removes `removes` measured drops and loses `loses` kept variants, with the kept fraction after."""

    name: str
    rule: str
    removes: int
    loses: int
    kept_fraction_after: float


class Survey(RubricModel):
    measured: int
    kept: int
    drops_by_condition: dict[str, int]
    by_value: dict[str, dict[str, Tally]]  # quantity -> value (as written) -> tally
    proposals: list[Proposal]

    @property
    def kept_fraction(self) -> float:
        return self.kept / self.measured if self.measured else 0.0


def _shown(value: Number) -> str:
    return f"{value:g}"


def quantities(parameters: Mapping[str, Number], varying: Iterable[str]) -> dict[str, Number]:
    """The varying parameters' values and every contact case's internal step, rounded to what a rule compares."""
    out = {name: parameters[name] for name in varying}
    for name, (dt, substeps) in STEPS.items():
        out[name] = round(parameters[dt] / parameters[substeps], 12)
    return out


def _rule(quantity: str, values: list[Number]) -> str:
    dt, substeps = STEPS.get(quantity, (None, None))
    expr = f"{dt} / {substeps}" if dt else quantity
    return " or ".join(f"close({expr}, {_shown(v)})" for v in sorted(values))


def survey(outcomes: list[Outcome], varying: Iterable[str]) -> Survey:
    """Tally `outcomes` by lab condition and by the value of each varying parameter and internal step, and propose
    for each quantity the rule keeping only the values some kept variant has, where that removes at least one drop and
    loses no kept variant (best first: most drops removed, then fewest values kept)."""
    varying = sorted(varying)
    counts: dict[str, dict[str, Counter]] = {}
    seen: dict[str, dict[str, Number]] = {}
    for o in outcomes:
        for quantity, value in quantities(o.parameters, varying).items():
            counts.setdefault(quantity, {}).setdefault(_shown(value), Counter())[o.kept] += 1
            seen.setdefault(quantity, {})[_shown(value)] = value
    by_value = {q: {v: Tally(kept=c[True], dropped=c[False]) for v, c in values.items()}
                for q, values in counts.items()}
    kept = sum(o.kept for o in outcomes)
    proposals = []
    for quantity, tallies in by_value.items():
        keep = [seen[quantity][v] for v, t in tallies.items() if t.kept]
        removes = sum(t.dropped for t in tallies.values() if not t.kept)
        if not keep or not removes or len(keep) == len(tallies):
            continue
        remaining = sum(t.measured for t in tallies.values() if t.kept)
        proposals.append(Proposal(name=f"{quantity}_as_measured", rule=_rule(quantity, keep), removes=removes,
                                  loses=0, kept_fraction_after=kept / remaining))
    proposals.sort(key=lambda p: (-p.removes, p.rule.count(" or "), p.name))
    drops = Counter(c for o in outcomes if not o.kept for c in (o.failed or ["unknown"]))
    return Survey(measured=len(outcomes), kept=kept, drops_by_condition=dict(drops.most_common()),
                  by_value={q: dict(sorted(t.items(), key=lambda kv: seen[q][kv[0]])) for q, t in sorted(by_value.items())},
                  proposals=proposals)


def report_lines(s: Survey, title: str) -> list[str]:
    """The survey as text: what tools.variant_space prints and docs/variants.md quotes."""
    lines = [title, f"  kept {s.kept} of {s.measured} measured variants ({s.kept_fraction:.0%})"]
    if s.drops_by_condition:
        lines.append("  drops by failed condition: " + ", ".join(f"{c} x{n}" for c, n in s.drops_by_condition.items()))
    lines.append("  kept/measured by value:")
    for quantity, tallies in s.by_value.items():
        cells = "  ".join(f"{v}: {t.kept}/{t.measured}" for v, t in tallies.items())
        lines.append(f"    {quantity:24s} {cells}")
    if s.proposals:
        lines.append("  proposed constraints (each loses no kept variant):")
        lines += [f"    {p.name}: {p.rule}  (removes {p.removes} drops; kept fraction after "
                  f"{p.kept_fraction_after:.0%})" for p in s.proposals]
    else:
        lines.append("  no constraint on one quantity separates the drops from the kept variants")
    return lines
