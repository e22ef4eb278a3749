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
    evidence: dict[str, str] = {}  # each failed condition's evidence, as the lab check wrote it
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


def checked_quantities(choices: Mapping[str, Iterable[Number]], case_names: Iterable[str]) -> set[str]:
    """The varying parameters any of whose values changes one of `case_names` (the lab check's cases) from the
    lesson's, and the internal steps of those contact cases among them."""
    from .apply import variant_cases  # here: survey is imported without building cases otherwise

    names = list(case_names)
    shipped = variant_cases({})
    out = set()
    for name, values in choices.items():
        for value in values:
            try:
                cases = variant_cases({name: value})
            except ValueError:  # a value building no valid case on its own still varies what the check runs
                out.add(name)
                break
            if any(cases[c] != shipped[c] for c in names):
                out.add(name)
                break
    return out | {step for step in STEPS if step.split("_")[0] in names}


def _rule(quantity: str, values: list[Number]) -> str:
    dt, substeps = STEPS.get(quantity, (None, None))
    expr = f"{dt} / {substeps}" if dt else quantity
    return " or ".join(f"close({expr}, {_shown(v)})" for v in sorted(values))


def survey(outcomes: list[Outcome], varying: Iterable[str], *, min_support: int = 2,
           checked: Iterable[str] | None = None) -> Survey:
    """Tally `outcomes` by lab condition and by the value of each varying parameter and internal step, and propose
    for each quantity the rule that excludes its values measured at least `min_support` times and never kept (a value
    seen once says little), where that loses no kept variant (best first: most drops removed, then shortest rule).
    When every value never kept is excluded so, the rule lists the values kept instead. With `checked` (the quantities
    that change a case the lab check runs: checked_quantities), only those are proposed: a drop cannot come from a
    parameter the check never ran."""
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
        if checked is not None and quantity not in set(checked):
            continue
        keep = [seen[quantity][v] for v, t in tallies.items() if t.kept]
        excluded = [v for v, t in tallies.items() if not t.kept and t.measured >= min_support]
        if not keep or not excluded:
            continue
        removes = sum(tallies[v].dropped for v in excluded)
        if len(keep) + len(excluded) == len(tallies):
            rule = _rule(quantity, keep)
        else:
            rule = " and ".join(f"not {_rule(quantity, [seen[quantity][v]])}" for v in excluded)
        remaining = sum(t.measured for v, t in tallies.items() if v not in excluded)
        proposals.append(Proposal(name=f"{quantity}_as_measured", rule=rule, removes=removes,
                                  loses=0, kept_fraction_after=kept / remaining))
    proposals.sort(key=lambda p: (-p.removes, len(p.rule), p.name))
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
    if s.kept == s.measured:
        lines.append("  no drops: nothing to propose")
    elif s.proposals:
        lines.append("  proposed constraints (each loses no kept variant):")
        lines += [f"    {p.name}: {p.rule}  (removes {p.removes} drops; kept fraction after "
                  f"{p.kept_fraction_after:.0%})" for p in s.proposals]
    else:
        lines.append("  no constraint on one quantity separates the drops from the kept variants")
    return lines
