"""L02 as a lesson declaration (rubric.lesson.Lesson), installed under the entry point `L02` (pyproject.toml).

Everything L02 owns is in this folder: its case kind and scene (specs.py, scenes.py), metrics, sheet, scoring rules,
lab check, reviewed rubric and Chinese texts. Nothing of the service names it.
"""

from __future__ import annotations

from pathlib import Path

from rubric.lesson import Lesson, SeriesChart

from . import check, metrics, scoring, sheet
from .specs import CASES, DropCase


def _first_contact(m) -> str:
    t = m.get("first_contact_t")
    return f"first contact at t={t:.3f} s" if t is not None else "no contact reported"


# The report's charts (drawn in the reader's browser from each run's stored arrays); each caption gives every run's
# key numbers from its stored metrics (metrics.DropMetrics).
CHARTS = (
    SeriesChart(id="drop-z", kind="drop", series="z", title="The box's centre height z, every run", axis="z (m)",
                words=lambda m: f"z({m['query_t']:.2f} s) = {m['z_at_query']:.4f} m, {_first_contact(m)}",
                first_contact="first_contact_t"),
    SeriesChart(id="drop-vz", kind="drop", series="vz", title="The box's vertical velocity vz, every run",
                axis="vz (m/s)", words=lambda m: f"vz({m['query_t']:.2f} s) = {m['vz_at_query']:.3f} m/s",
                first_contact="first_contact_t"),
    SeriesChart(id="drop-contact", kind="drop", series="contact_count", title="Box–ground contact count, every run",
                axis="contacts", words=lambda m: f"{_first_contact(m)}; {m['samples']} samples to t={m['final_t']:.2f} s",
                first_contact="first_contact_t", stepped=True),
)

LESSON = Lesson(
    name="L02",
    titles={"en": "L02 · The simulation lifecycle: one box, built, stepped and observed",
            "zh": "L02 · 仿真生命周期：一个盒子的构建、步进与观测"},
    languages=("en", "zh"),
    files=Path(__file__).parent,
    case_kinds={"drop": DropCase},
    scenes="lessons.l02.scenes",
    warm_up_cases=("S1", "S2"),
    cases=CASES,
    check_cases=check.CHECK_CASES,
    scoring_rules=scoring.SCORING_RULES,
    grade_sheet=scoring.grade_sheet,
    cases_to_run=scoring.cases_to_run,
    evaluate_check=check.evaluate,
    verdict_line=check.verdict_line,
    runs_read=scoring.runs_read,
    physics_key=scoring.physics_key,
    parse_sheet=sheet.parse_sheet,
    config_findings=scoring.findings,
    sheet_model=sheet.Sheet,
    lesson_run_specs=scoring.lesson_run_specs,
    checkpoint_ids=sheet.CHECKPOINT_IDS,
    expected_arrays=metrics.expected_arrays,
    case_metrics=metrics.case_metrics,
    metrics_models={"drop": metrics.DropMetrics},
    part_titles={"A": "Predictions: the falling box", "checkpoint": "Concept checkpoints: counting steps and time",
                 "hands_on": "Exercise: your own timing"},
    charts=CHARTS,
)
