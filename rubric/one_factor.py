"""The one-factor rule: each submitted config compared field by field with the baseline its rubric rule declares.

Only the fields a rule lists may differ. Visual-layer fields (Surface colours) are reported but never violate the
rule: they are not engine inputs of the physics, so they cannot confound a comparison. Under a student's variant the
lesson's cases are the variant's (rubric.variants), so "only table friction changed" is judged against their baseline.
"""

from __future__ import annotations

from pydantic import BaseModel

from .cases import BASELINE_CASES
from .rubrics import ConfigRule, Rubric
from .sheet import PredictionSheet
from .specs import ContactCase, FieldChange, FrictionCase, field_changes
from .variants import CaseSet, Variant, variant_cases


class ConfigFinding(BaseModel):
    """How one submitted config compares with its declared baseline, field by field."""

    role: str
    baseline: str
    may_change: list[str]
    changes: list[FieldChange]
    violations: list[FieldChange]

    @property
    def ok(self) -> bool:
        return not self.violations

    def describe(self) -> str:
        visual = [c for c in self.changes if c.visual]
        note = ("; visual only, not a physical input: " + ", ".join(f"{c.field} {c.baseline} -> {c.config}" for c in visual)
                if visual else "")
        if self.ok:
            physical = [c for c in self.changes if not c.visual]
            changed = ", ".join(f"{c.field} {c.baseline} -> {c.config}" for c in physical) or "nothing"
            return f"{self.role} vs {self.baseline}: one factor ({changed}){note}"
        lines = "; ".join(f"{c.field}: {c.baseline} -> {c.config}" for c in self.violations)
        return (f"{self.role} vs {self.baseline}: too many inputs changed at once; only "
                f"{', '.join(self.may_change) or 'nothing'} may change, but also: {lines}{note}")


def lesson_cases(variant: Variant | None = None) -> CaseSet:
    """The case table a student's configs are compared with: their variant's, or the lesson's shipped one."""
    return BASELINE_CASES if variant is None else variant_cases(variant.parameters)


def role_baseline(role: str, rubric: Rubric, variant: Variant | None = None) -> ContactCase | FrictionCase:
    """The lesson case a role's config starts from and is compared with (the form's starting config), under the
    student's variant when given: e.g. table_exercise -> the variant's friction-baseline."""
    return lesson_cases(variant)[rubric.configs[role].baseline]


def one_factor_findings(sheet: PredictionSheet, rubric: Rubric, variant: Variant | None = None
                        ) -> dict[str, ConfigFinding]:
    """For every submitted config, the field-by-field comparison with the baseline its rubric rule declares: the
    student's own config of that role, else the lesson's case, taken from the student's variant when given."""
    cases = lesson_cases(variant)
    findings = {}
    for role, spec in sheet.configs.submitted().items():
        rule: ConfigRule = rubric.configs[role]
        # A role declared against itself (N1 vs N1) is compared with the lesson's case, not with its own copy.
        base = cases[rule.baseline] if rule.baseline == role else sheet.spec_for(rule.baseline, cases)
        changes = field_changes(base, spec)
        findings[role] = ConfigFinding(
            role=role,
            baseline=rule.baseline,
            may_change=rule.may_change,
            changes=changes,
            violations=[c for c in changes if c.field not in rule.may_change and not c.visual],
        )
    return findings
