"""The scorer: grade a prediction sheet item by item against what Genesis measured, under a rubric version.

Each item names a scoring rule (registered by the part modules of this package). A rule returns an Outcome: the
verdict, what was expected and the evidence with the backend of every run it read. Verdicts:
- credit / no_credit: the prediction matches the expected answer, or not;
- inconclusive: the measured difference is inside the reviewed tolerance (not counted either way);
- one_factor_violation: a run the item compares comes from a config that changed more than one factor;
- not_measured: a run the item needs failed or was never run (no credit, visible).
A config fault voids only the items that read the run it concerns: a rule that reads a role whose config broke
the one-factor rule is stopped there and says which config and why; every other item keeps its score.
Under a student's variant (rubric.variants) the lesson's cases, the one-factor baselines and the numbers the expected
answers name are the variant's, and a lesson run measured under other parameters is not graded (not_measured, named);
with no variant everything is the lesson's shipped table, exactly as before variants existed.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Collection, Mapping
from dataclasses import dataclass, field
from typing import Literal

from pydantic import BaseModel

from ..cases import COLOR_SWAP
from ..check import CheckOutcome
from ..guards import gradable
from ..metrics import ContactMetrics, FrictionMetrics, LaneMetrics
from ..one_factor import ConfigFinding, lesson_cases, one_factor_findings
from ..lesson import SHEET_CASE_PREFIX
from ..results import CaseResult
from ..rubrics import Item, Rubric, load_rubric, version_key
from ..sheet import PredictionSheet, answered
from ..specs import field_changes
from ..variants import CaseSet, Variant, complete_parameters
from ..variants.texts import item_question

Verdict = Literal["credit", "no_credit", "inconclusive", "one_factor_violation", "not_measured"]
# Lesson cases every sheet is graded on (when the sheet does not replace them with its own config). The lab check
# (rubric.check) needs N1-N4 and both friction runs, so friction-table-0.30 is here although no item reads it: the
# check stored with each grade is then evaluated on the submission's own runs. Measurements are reused across
# students by content key (worker/reuse.py), so it costs one friction case once per engine version.
LESSON_RUNS = ("N1", "N2", "N3", "N4", "friction-baseline", "friction-table-0.30", COLOR_SWAP)
# The lesson case that measures what a student's config role is asked to be: the sheet's table exercise at 0.30 is
# friction-table-0.30, its extension N5. Where the sheet submits no such config (a checkpoint sheet), the lesson case
# is what would tell the answer of an item reading the role (`runs_read`).
ROLE_LESSON_CASES = {"table_exercise": "friction-table-0.30", "extension": "N5"}
EVERY_RUN = "every run"  # a rule that reads every run of the submission (the engine version of their provenance)


class ItemGrade(BaseModel):
    id: str
    question: str
    part: str
    kind: str
    points: float
    score: float
    max_score: float  # 0 when inconclusive: neither credited nor penalized
    verdict: Verdict
    prediction: str
    expected: str
    measured: str = ""  # what the runs showed, in words with units (empty where nothing was measured)
    feedback: str
    evidence: dict[str, float | int | None]
    backends: dict[str, str]
    tolerances: dict[str, str]


class GradeReport(BaseModel):
    lesson: str
    student: str
    rubric_version: str
    rubric_hash: str
    engine_version: str
    total: float
    max_total: float
    complete: bool  # False when any item could not be measured
    items: list[ItemGrade]
    config_findings: list[str]
    # The lab check (L03 CHECK line and its conditions) evaluated on the submission's own runs where it was graded;
    # None for grades stored before it was recorded.
    check: CheckOutcome | None = None
    # The variant graded (rubric.variants.Variant.id); None: the lesson's shipped parameters.
    variant: str | None = None

    def item(self, item_id: str) -> ItemGrade:
        return next(i for i in self.items if i.id == item_id)


class NotMeasured(Exception):
    """A case this item needs has no valid measurement (failed, invalid, timed out or not run)."""


class ConfigViolation(Exception):
    """A run this item needs comes from a config that broke the one-factor rule (it was never run)."""

    def __init__(self, finding: ConfigFinding):
        super().__init__(finding.describe())
        self.finding = finding


@dataclass
class Outcome:
    verdict: Verdict
    expected: str
    measured: str = ""
    evidence: dict[str, float | int | None] = field(default_factory=dict)
    backends: dict[str, str] = field(default_factory=dict)


def case_name(sheet: PredictionSheet, role_or_case: str) -> str:
    """Name a role's case runs under: the student's config is renamed so it never collides with a lesson case."""
    if role_or_case in sheet.configs.submitted():
        return SHEET_CASE_PREFIX + role_or_case
    return role_or_case


def lesson_run_specs(variant: Variant | None = None) -> list:
    """The lesson runs every sheet on `variant` is graded on (LESSON_RUNS, the variant's cases): what a pool measures
    ahead of time, so that each student on the variant reuses them (the lab check reads a subset: CHECK_CASES)."""
    cases = lesson_cases(variant)
    return [cases[name] for name in LESSON_RUNS]


def cases_to_run(sheet: PredictionSheet, rubric: Rubric | None = None, variant: Variant | None = None) -> list:
    """Every case grading needs: lesson cases not replaced by the sheet (the variant's, when given), plus its configs
    that obey the one-factor rule (a config that breaks it is graded as such, never run as if valid). Unique names.

    A sheet of concept checkpoints only submits no config, so it needs the lesson's own cases alone: the same runs for
    every student. The service grades such a sheet as it is submitted where all are stored
    (grader.services.submissions.submit.submit, through grader.core.grading.grade_and_store) and queues them only
    while one was never measured."""
    rubric = rubric or load_rubric(sheet.lesson)
    findings = one_factor_findings(sheet, rubric, variant)
    cases = lesson_cases(variant)
    specs = {}
    for name in LESSON_RUNS:
        if name not in sheet.configs.submitted():
            specs[name] = cases[name]
    for role, spec in sheet.configs.submitted().items():
        if findings[role].ok:
            run_name = case_name(sheet, role)
            specs[run_name] = type(spec).model_validate(
                {**spec.model_dump(exclude_computed_fields=True), "name": run_name}
            )
    return list(specs.values())


class Context:
    """What a check may read: the sheet, its item's reviewed tolerances, and the measured runs by role."""

    def __init__(self, sheet: PredictionSheet, results: Mapping[str, CaseResult], rubric: Rubric,
                 findings: Mapping[str, ConfigFinding], variant: Variant | None = None):
        self.sheet, self.results, self.rubric, self.findings = sheet, results, rubric, findings
        self.variant = variant
        # The lesson's case table and parameters this sheet is graded under: its variant's, else the shipped ones.
        self.cases: CaseSet = lesson_cases(variant)
        self.parameters = complete_parameters(variant.parameters if variant else None)
        self.item: Item | None = None

    def tol(self, name: str) -> float:
        """A reviewed tolerance the current item declares; reading an undeclared one is a rubric bug, not a grade."""
        if name not in self.item.tolerances:
            raise KeyError(f"item {self.item.id} reads tolerance {name!r} but declares only {self.item.tolerances}")
        return self.rubric.tolerances[name].value

    def spec(self, role: str):
        return self.sheet.spec_for(role, self.cases)

    def run_name(self, role: str) -> str:
        return case_name(self.sheet, role)

    def result(self, role: str) -> CaseResult:
        if self.item is not None:
            declared = RULE_READS[self.item.check]
            if declared != EVERY_RUN and role not in declared:
                raise KeyError(f"item {self.item.id} reads the run of {role!r} but its rule {self.item.check!r} "
                               f"declares only {declared}")
        finding = self.findings.get(role)
        if finding is not None and not finding.ok:
            raise ConfigViolation(finding)
        name = self.run_name(role)
        result = self.results.get(name)
        if result is None:
            raise NotMeasured(f"case {name} ({role}) was not run")
        if not result.ok:
            raise NotMeasured(f"case {name} ({role}) {result.status} on {result.backend}: {result.error}")
        if result.metrics is None:
            raise NotMeasured(f"case {name} ({role}) has no stored metrics")
        if self.variant is not None and name in self.cases:
            other = variant_mismatch(self.cases[name], result.spec)
            if other:
                raise NotMeasured(f"case {name} ({role}) was measured with other parameters than variant "
                                  f"{self.variant.id}: {other}")
        return result

    def backend(self, role: str) -> str:
        return self.result(role).backend

    def contact(self, role: str) -> ContactMetrics:
        return self.result(role).metrics

    def friction(self, role: str) -> FrictionMetrics:
        return self.result(role).metrics

    def lane(self, role: str, lane: str) -> LaneMetrics:
        return self.friction(role).lane(lane)

    def backends(self, *roles: str) -> dict[str, str]:
        return {self.run_name(role): self.backend(role) for role in roles}

    def maybe(self, fn: Callable, *args):
        """Supporting evidence: None when that run was not measured or its config broke the one-factor rule."""
        try:
            return fn(*args)
        except (NotMeasured, ConfigViolation):
            return None


# Where the variant's case and a measured lesson run may differ: where and how it ran, and its label (not physics).
EXECUTION_FIELDS = {"backend", "precision", "render", "name"}


def variant_mismatch(expected, measured) -> str:
    """The physical inputs in which a measured lesson run differs from the variant's case ('' when none)."""
    changes = [c for c in field_changes(expected, measured) if c.field not in EXECUTION_FIELDS]
    return ", ".join(f"{c.field} {c.baseline} expected, {c.config} measured" for c in changes)


# Each rubric item names its scoring rule in its `check` field (the key stays: a version's content hash covers it).
SCORING_RULES: dict[str, Callable[[Context, Item, object], Outcome]] = {}
# {rule name: the roles whose runs it may read, or EVERY_RUN}: declared with the rule, enforced by Context.result (a
# rule reading an undeclared role is a rubric bug, as reading an undeclared tolerance is), and read by the service to
# withhold every run that could answer a withheld item, whatever its verdict and in whichever submission (`runs_read`).
RULE_READS: dict[str, tuple[str, ...] | str] = {}


def scoring_rule(name: str, *, reads: tuple[str, ...] | str):
    """Register a scoring rule under the name rubric items give in their `check` field, with the roles of the runs it
    reads (lesson case names or a sheet's config roles; EVERY_RUN for all of them)."""
    def register(fn):
        SCORING_RULES[name] = fn
        RULE_READS[name] = reads
        return fn
    return register


def runs_read(rubric: Rubric, item_id: str, runs: Collection[str]) -> list[str]:
    """The runs among `runs` (a submission's, by name) whose measurements could tell item `item_id`'s answer: for
    each role its rule reads (RULE_READS), the sheet's run of it, the lesson case of that name and the lesson case that
    measures what the role is asked to be (ROLE_LESSON_CASES); every run for a rule reading every run. None for an
    item the rubric decides without measurement (conceptual, config). Whatever the item's verdict: a run that broke
    the one-factor rule or failed is still what the item asks about."""
    item = next((i for i in rubric.items if i.id == item_id), None)
    if item is None or item.kind not in ("measured", "computed"):
        return []
    declared = RULE_READS[item.check]
    if declared == EVERY_RUN:
        return sorted(runs)
    names = {name for role in declared
             for name in (SHEET_CASE_PREFIX + role, role, ROLE_LESSON_CASES.get(role))}
    return sorted(name for name in runs if name in names)


def credit(ok: bool) -> "Verdict":
    return "credit" if ok else "no_credit"


def relation_verdict(predicted: str, measured: list[str | None]) -> "Verdict":
    """A decisive measurement against the prediction refutes it; otherwise any unresolved one leaves it open."""
    if any(m is not None and m != predicted for m in measured):
        return "no_credit"
    if any(m is None for m in measured):
        return "inconclusive"
    return "credit"


def _prediction(answer) -> str:
    return json.dumps(answer.model_dump(mode="json", exclude={"explanation"}), separators=(", ", ": "))


def _tolerances(rubric: Rubric, item: Item) -> dict[str, str]:
    return {name: f"{rubric.tolerances[name].value:g} {rubric.tolerances[name].unit}" for name in item.tolerances}


_VERDICT_TEXT = {
    "credit": "credit: the prediction matches",
    "no_credit": "no credit: the prediction does not match",
    "inconclusive": "inconclusive: the measured difference is inside the reviewed tolerance, so the direction is "
                    "neither credited nor penalized (not counted)",
    "one_factor_violation": "one-factor violation: a run this item compares comes from a config that changed too many "
                            "inputs at once, so the comparison is not interpretable",
    "not_measured": "not measured: no valid result for a case this item needs; no credit until it is measured",
}
_HOW = {
    "measured": "Decided by measurement",
    "config": "Decided from the submitted configs",
    "computed": "Computed from the configs",
    "conceptual": "Conceptual: no run can decide this answer; the measured evidence only illustrates it",
}


def _grade_item(ctx: Context, item: Item) -> ItemGrade:
    answer = getattr(ctx.sheet.answers, item.id)
    ctx.item = item
    try:
        outcome = SCORING_RULES[item.check](ctx, item, answer)
    except ConfigViolation as exc:
        outcome = Outcome("one_factor_violation", "a one-factor config", str(exc))
    except NotMeasured as exc:
        outcome = Outcome("not_measured", "a measured result", str(exc))
    # Under a variant the question names the variant's numbers (rubric.variants.texts); else the rubric's text.
    return item_grade(item, answer, outcome, ctx.rubric, question=item_question(item, ctx.variant))


def item_grade(item: Item, answer, outcome: Outcome, rubric: Rubric, *, question: str | None = None) -> ItemGrade:
    """One item's grade from its rule's outcome: the score, and feedback saying how it was decided, the prediction,
    the expected answer, the evidence with its backends, the tolerances and the verdict. Every lesson's scorer builds
    its items with it, so that a report reads the same whatever the lesson."""
    tolerances = _tolerances(rubric, item)
    feedback = [f"{_HOW[item.kind]}.", f"Prediction: {_prediction(answer)}.", f"Expected: {outcome.expected}."]
    if outcome.measured:
        on = ", ".join(f"{case} on {backend}" for case, backend in outcome.backends.items())
        feedback.append(f"Evidence: {outcome.measured}" + (f" [{on}]." if on else "."))
    if tolerances:
        feedback.append("Tolerance: " + ", ".join(f"{k} = {v}" for k, v in tolerances.items()) + ".")
    feedback.append(f"Verdict: {_VERDICT_TEXT[outcome.verdict]}.")
    counted = outcome.verdict != "inconclusive"
    return ItemGrade(
        id=item.id, question=question if question is not None else item.question, part=item.part, kind=item.kind,
        points=item.points,
        score=item.points if outcome.verdict == "credit" else 0.0,
        max_score=item.points if counted else 0.0,
        verdict=outcome.verdict, prediction=_prediction(answer), expected=outcome.expected, measured=outcome.measured,
        feedback=" ".join(feedback), evidence=outcome.evidence, backends=outcome.backends, tolerances=tolerances,
    )


class ArchivedRubric(ValueError):
    """A rubric version whose checks are no longer implemented: its stored grades stay readable, no new grading."""


# The checks of this package implement these rubric versions and later; grades stored under an earlier version
# stay readable (its file still loads), but grading under it would run today's checks under yesterday's items.
GRADABLE_FROM = {"L03": "2"}


def ensure_gradable(rubric: Rubric) -> None:
    first = GRADABLE_FROM.get(rubric.lesson)
    if first is not None and version_key(rubric.version) < version_key(first):
        raise ArchivedRubric(
            f"rubric {rubric.lesson} v{rubric.version} is archived: grades stored under it stay readable, but new "
            f"grading needs v{first} or later")


def grade_sheet(sheet: PredictionSheet, results: Mapping[str, CaseResult], rubric: Rubric | None = None,
                variant: Variant | None = None) -> GradeReport:
    """Grade every rubric item the sheet answers (all, or one assignment's part: the other items neither score nor
    count in max_total); failed or missing results give visible not_measured items, never a crash or credit.

    `variant`: the student's own lab (its lesson runs must have been measured with its parameters); None grades on the
    lesson's shipped cases."""
    rubric = rubric or load_rubric(sheet.lesson)
    if rubric.lesson != sheet.lesson:
        raise ValueError(f"rubric is for lesson {rubric.lesson}, the sheet for {sheet.lesson}")
    ensure_gradable(rubric)
    results = gradable(dict(results), rubric)  # provenance violations: kept, never graded, the reason shown
    findings = one_factor_findings(sheet, rubric, variant)
    ctx = Context(sheet, results, rubric, findings, variant)
    held = set(answered(sheet))
    items = [_grade_item(ctx, item) for item in rubric.items if item.id in held]
    return GradeReport(
        lesson=sheet.lesson, student=sheet.student, rubric_version=rubric.version, rubric_hash=rubric.content_hash,
        engine_version=rubric.engine_version,
        total=sum(i.score for i in items), max_total=sum(i.max_score for i in items),
        complete=all(i.verdict != "not_measured" for i in items),
        items=items, config_findings=[f.describe() for f in findings.values()],
        variant=variant.id if variant is not None else None,
    )
