"""L02's scoring rules: every item decided by what its runs measured, under the reviewed tolerances of its rubric.

The counts (samples, internal updates), the simulated time and the internal dt are read from the engine's own report
of each run (its provenance's discretization), never from the spec that asked for them. The box's height, velocity
and first touch are read from the sampled arrays (lessons.l02.metrics). The exercise's config must change only the
timing of S1 (its rubric rule); one that changes more is not run, and E1 says why.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping

from rubric.guards import gradable
from rubric.lesson import SHEET_CASE_PREFIX, answered
from rubric.one_factor import ConfigFinding
from rubric.results import CaseResult
from rubric.rubrics import Rubric, load_rubric
from rubric.scoring.scorer import GradeReport, Outcome, item_grade
from rubric.specs import field_changes

from .specs import CASES, QUERY_T_S, DropCase, free_fall, touch_time

LESSON_RUNS = ("S1", "S2")
EXERCISE = "exercise"


class _Stop(Exception):
    """An item cannot be decided: its outcome says why (not measured, or a config that broke its rule)."""

    def __init__(self, outcome: Outcome):
        super().__init__(outcome.measured)
        self.outcome = outcome


def findings(sheet, rubric: Rubric, variant=None) -> dict[str, ConfigFinding]:
    """Each submitted config compared field by field with its rule's baseline (a lesson case; L02 has no variants)."""
    out = {}
    for role, spec in sheet.configs.submitted().items():
        rule = rubric.configs[role]
        changes = field_changes(CASES[rule.baseline], spec)
        out[role] = ConfigFinding(role=role, baseline=rule.baseline, may_change=rule.may_change, changes=changes,
                                  violations=[c for c in changes if c.field not in rule.may_change and not c.visual])
    return out


def lesson_run_specs(variant=None) -> list[DropCase]:
    """The lesson's own runs every sheet is graded on."""
    return [CASES[name] for name in LESSON_RUNS]


def cases_to_run(sheet, rubric: Rubric | None = None, variant=None) -> list[DropCase]:
    """S1 and S2, and the exercise's config under its run name when it obeys its rule."""
    if variant is not None:
        raise ValueError("L02 has no variant space: its sheets run the lesson's own cases")
    rubric = rubric or load_rubric(sheet.lesson)
    specs = lesson_run_specs()
    for role, finding in findings(sheet, rubric).items():
        if finding.ok:
            spec = sheet.configs.submitted()[role]
            specs.append(DropCase.model_validate({**spec.model_dump(exclude_computed_fields=True),
                                                  "name": SHEET_CASE_PREFIX + role}))
    return specs


def runs_read(item_id: str, runs) -> list[str]:
    """The runs whose measurements could tell an item's answer (withheld with it): E1 reads the exercise's run, every
    other item the lesson's two runs."""
    wanted = {SHEET_CASE_PREFIX + EXERCISE} if item_id == "E1" else set(LESSON_RUNS)
    return [run for run in runs if run in wanted]


def physics_key(kind: str, spec) -> str | None:
    """Every L02 run integrates the same drop; what differs is its internal step (dt / substeps)."""
    try:
        case = DropCase.model_validate(spec) if kind == "drop" else None
    except ValueError:
        return None
    return None if case is None else f"drop:{case.substep_dt:.9g}"


class _Runs:
    """The runs an item reads, by name; a missing or failed one stops the item (not measured)."""

    def __init__(self, results: Mapping[str, CaseResult], found: Mapping[str, ConfigFinding]):
        self.results, self.found = results, found

    def __call__(self, name: str) -> CaseResult:
        role = name.removeprefix(SHEET_CASE_PREFIX)
        if role in self.found and not self.found[role].ok:
            raise _Stop(Outcome("one_factor_violation", "a config that changes only the timing",
                                self.found[role].describe()))
        result = self.results.get(name)
        if result is None or not result.ok:
            why = "was never run" if result is None else f"{result.status}: {result.error or 'no valid result'}"
            raise _Stop(Outcome("not_measured", "a measured result", f"run {name} {why}"))
        return result


def _window(result: CaseResult):
    return result.provenance.discretization


def _close(a: float, b: float, tolerance: float) -> bool:
    return abs(a - b) <= tolerance


def _tol(rubric: Rubric, name: str) -> float:
    return rubric.tolerances[name].value


def rule_sample_counts(runs, rubric, answer) -> Outcome:
    s1, s2 = runs("S1"), runs("S2")
    got = {"S1": _window(s1).sample_count, "S2": _window(s2).sample_count}
    ok = answer.S1 == got["S1"] and answer.S2 == got["S2"]
    return Outcome("credit" if ok else "no_credit", f"S1 {got['S1']} samples, S2 {got['S2']}",
                   f"the engine sampled S1 {got['S1']} times and S2 {got['S2']} times (n_steps = duration / dt)",
                   {"S1_samples": got["S1"], "S2_samples": got["S2"]}, {n: r.backend for n, r in (("S1", s1), ("S2", s2))})


def rule_internal_updates(runs, rubric, answer) -> Outcome:
    s1, s2 = runs("S1"), runs("S2")
    w1, w2 = _window(s1), _window(s2)
    internal_dt = w2.substep_dt
    ok = (answer.S1 == w1.internal_updates and answer.S2 == w2.internal_updates
          and math.isclose(answer.internal_dt.si, internal_dt, rel_tol=_tol(rubric, "computed_relative")))
    return Outcome("credit" if ok else "no_credit",
                   f"S1 {w1.internal_updates} internal updates, S2 {w2.internal_updates}; S2's internal dt "
                   f"{internal_dt * 1000:g} ms",
                   f"the engine counted {w1.internal_updates} substeps in S1 and {w2.internal_updates} in S2 "
                   f"(n_steps x substeps), S2 at substep_dt {internal_dt:g} s",
                   {"S1_internal_updates": w1.internal_updates, "S2_internal_updates": w2.internal_updates,
                    "S2_substep_dt": internal_dt}, {"S1": s1.backend, "S2": s2.backend})


def rule_simulated_time(runs, rubric, answer) -> Outcome:
    s1, s2 = runs("S1"), runs("S2")
    t1, t2 = _window(s1).duration, _window(s2).duration
    tol = _tol(rubric, "reported_time")
    ok = _close(answer.S1.si, t1, tol) and _close(answer.S2.si, t2, tol)
    return Outcome("credit" if ok else "no_credit", f"S1 {t1:.4g} s, S2 {t2:.4g} s",
                   f"the engine's clock advanced {t1:.6g} s in S1 and {t2:.6g} s in S2 (n_steps x dt)",
                   {"S1_simulated_s": t1, "S2_simulated_s": t2}, {"S1": s1.backend, "S2": s2.backend})


def rule_height_at_query(runs, rubric, answer) -> Outcome:
    s1 = runs("S1")
    z = s1.metrics.z_at_query
    exact, _ = free_fall(QUERY_T_S)
    ok = _close(answer.height.si, z, _tol(rubric, "reported_height"))
    return Outcome("credit" if ok else "no_credit", f"{z:.4f} m (measured in S1)",
                   f"S1's box centre was at {z:.4f} m at t = {s1.metrics.query_t:.4g} s; exact free fall gives "
                   f"{exact:.4f} m (difference {z - exact:+.4f} m)",
                   {"S1_z_at_query": z, "free_fall_z": exact}, {"S1": s1.backend})


def rule_velocity_at_query(runs, rubric, answer) -> Outcome:
    s1 = runs("S1")
    vz = s1.metrics.vz_at_query
    _, exact = free_fall(QUERY_T_S)
    ok = _close(answer.vz_m_per_s, vz, _tol(rubric, "reported_velocity"))
    return Outcome("credit" if ok else "no_credit", f"{vz:.3f} m/s (measured in S1)",
                   f"S1's box fell at {vz:.4f} m/s at t = {s1.metrics.query_t:.4g} s; exact free fall gives "
                   f"{exact:.4f} m/s", {"S1_vz_at_query": vz, "free_fall_vz": exact}, {"S1": s1.backend})


def rule_touch_time(runs, rubric, answer) -> Outcome:
    s1 = runs("S1")
    first = s1.metrics.first_contact_t
    if first is None:
        return Outcome("not_measured", "a run in which the box touches the ground",
                       f"S1 reported no contact with the ground in {s1.metrics.final_t:.3g} s",
                       {"S1_first_contact_t": None}, {"S1": s1.backend})
    ok = _close(answer.time.si, first, _tol(rubric, "touch_time_resolution"))
    return Outcome("credit" if ok else "no_credit", f"{first:.3f} s (the first S1 sample with a contact)",
                   f"S1's first sample reporting a box-ground contact is at t = {first:.4g} s; exact free fall "
                   f"reaches the ground at {touch_time():.4f} s", {"S1_first_contact_t": first,
                                                                   "free_fall_touch_t": touch_time()},
                   {"S1": s1.backend})


def rule_lower_run(runs, rubric, answer) -> Outcome:
    s1, s2 = runs("S1"), runs("S2")
    dz = s1.metrics.z_at_query - s2.metrics.z_at_query
    resolution = _tol(rubric, "height_difference_resolution")
    expected = "same" if abs(dz) <= resolution else ("S1" if dz < 0 else "S2")
    return Outcome("credit" if answer.lower == expected else "no_credit", expected,
                   f"at t = {QUERY_T_S:g} s S1's box is {dz:+.4f} m relative to S2's", {"S1_minus_S2_z": dz},
                   {"S1": s1.backend, "S2": s2.backend})


def rule_exercise_counts(runs, rubric, answer) -> Outcome:
    run = runs(SHEET_CASE_PREFIX + EXERCISE)
    w = _window(run)
    ok = answer.samples == w.sample_count and answer.internal_updates == w.internal_updates
    return Outcome("credit" if ok else "no_credit", f"{w.sample_count} samples, {w.internal_updates} internal updates",
                   f"your config ran {w.sample_count} outer steps of {w.dt:g} s with {w.substeps} substeps each",
                   {"samples": w.sample_count, "internal_updates": w.internal_updates},
                   {SHEET_CASE_PREFIX + EXERCISE: run.backend})


SCORING_RULES: dict[str, Callable] = {
    "sample_counts": rule_sample_counts,
    "internal_updates": rule_internal_updates,
    "simulated_time": rule_simulated_time,
    "height_at_query": rule_height_at_query,
    "velocity_at_query": rule_velocity_at_query,
    "touch_time": rule_touch_time,
    "lower_run": rule_lower_run,
    "exercise_counts": rule_exercise_counts,
}


def grade_sheet(sheet, results: Mapping[str, CaseResult], rubric: Rubric | None = None, variant=None) -> GradeReport:
    """Every item the sheet answers, graded on its runs; a failed or missing run makes the items reading it
    not_measured (visible, no credit), never a crash."""
    if variant is not None:
        raise ValueError("L02 has no variant space")
    rubric = rubric or load_rubric(sheet.lesson)
    if rubric.lesson != sheet.lesson:
        raise ValueError(f"rubric is for lesson {rubric.lesson}, the sheet for {sheet.lesson}")
    found = findings(sheet, rubric)
    runs = _Runs(gradable(dict(results), rubric), found)
    held = set(answered(sheet))
    items = []
    for item in rubric.items:
        if item.id not in held:
            continue
        answer = getattr(sheet.answers, item.id)
        try:
            outcome = SCORING_RULES[item.check](runs, rubric, answer)
        except _Stop as stop:
            outcome = stop.outcome
        items.append(item_grade(item, answer, outcome, rubric))
    return GradeReport(lesson=sheet.lesson, student=sheet.student, rubric_version=rubric.version,
                       rubric_hash=rubric.content_hash, engine_version=rubric.engine_version,
                       total=sum(i.score for i in items), max_total=sum(i.max_score for i in items),
                       complete=all(i.verdict != "not_measured" for i in items), items=items,
                       config_findings=[f.describe() for f in found.values()])


