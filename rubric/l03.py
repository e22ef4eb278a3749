"""L03 as a lesson declaration (rubric.lesson.Lesson): falling-cube contact, dt/substeps, friction and stopping
distance. Installed under the entry point `L03` (pyproject.toml); its modules are where they were (issue 45 moves
them into the lesson's own package step by step, tests/rubric/l03_golden.json guarding every grade)."""

from __future__ import annotations

from . import cases, check, scoring
from .lesson import Lesson
from .rubrics import LESSONS_DIR
from .specs import ContactCase, FrictionCase

LESSON = Lesson(
    name="L03",
    titles={"en": "L03 · Rigid-body contact, timesteps and friction",
            "zh": "L03 · 刚体接触、时间步长与摩擦"},
    languages=("en", "zh"),
    files=LESSONS_DIR,
    case_kinds={"contact": ContactCase, "friction": FrictionCase},
    scenes="worker.engine",
    cases=cases.BASELINE_CASES,
    check_cases=tuple(cases.CHECK_CASES),
    scoring_rules=scoring.SCORING_RULES,
    grade_sheet=scoring.grade_sheet,
    cases_to_run=scoring.cases_to_run,
    evaluate_check=check.evaluate,
    verdict_line=check.verdict_line,
    archived_versions=("1",),
)
