"""L03 as a lesson declaration (rubric.lesson.Lesson): falling-cube contact, dt/substeps, friction and stopping
distance. Installed under the entry point `L03` (pyproject.toml); its modules are where they were (issue 45 moves
them into the lesson's own package step by step, tests/rubric/l03_golden.json guarding every grade)."""

from __future__ import annotations

import functools

from . import cases, check, metrics, one_factor, results, scoring, sheet, specs
from .lesson import Lesson
from .metrics import ContactMetrics, FrictionMetrics
from .rubrics import LESSONS_DIR, load_rubric
from .specs import ContactCase, FrictionCase



@functools.lru_cache(maxsize=1)
def _latest_rubric():
    return load_rubric("L03")


def runs_read(item_id: str, runs) -> list[str]:
    """The runs of `runs` whose measurements could tell L03 item `item_id`'s answer (rubric.scoring.runs_read), by
    the latest rubric version: an item's rule and kind are the same in every version still graded."""
    return scoring.runs_read(_latest_rubric(), item_id, runs)


def physics_key(kind: str, spec) -> str | None:
    """The physics an L03 case integrates (rubric.specs.physics_key) from a stored spec; None for an invalid one."""
    model = {"contact": ContactCase, "friction": FrictionCase}.get(kind)
    try:
        return None if model is None else specs.physics_key(model.model_validate(spec))
    except ValueError:
        return None


LESSON = Lesson(
    name="L03",
    titles={"en": "L03 · Rigid-body contact, timesteps and friction",
            "zh": "L03 · 刚体接触、时间步长与摩擦"},
    languages=("en", "zh"),
    files=LESSONS_DIR,
    case_kinds={"contact": ContactCase, "friction": FrictionCase},
    scenes="lessons.l03.scenes",
    figures="lessons.l03.figures",
    # every scene structure of its cases (the friction cases share one; each contact discretisation is its own), the
    # two it always had first
    warm_up_cases=("N1", "friction-baseline", "N2", "N3", "N4", "N5"),
    cases=cases.BASELINE_CASES,
    check_cases=tuple(cases.CHECK_CASES),
    scoring_rules=scoring.SCORING_RULES,
    grade_sheet=scoring.grade_sheet,
    cases_to_run=scoring.cases_to_run,
    evaluate_check=check.evaluate,
    verdict_line=check.verdict_line,
    runs_read=runs_read,
    physics_key=physics_key,
    archived_versions=("1",),
    parse_sheet=sheet.parse_sheet,
    config_findings=one_factor.one_factor_findings,
    sheet_model=sheet.PredictionSheet,
    lesson_run_specs=scoring.lesson_run_specs,
    checkpoint_ids=sheet.CHECKPOINT_IDS,
    expected_arrays=results.expected_arrays,
    case_metrics=metrics.case_metrics,
    metrics_models={"contact": ContactMetrics, "friction": FrictionMetrics},
)
