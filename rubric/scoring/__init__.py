"""Scoring: the engine (engine.py) and the checks of each part of the lesson, registered by importing them.

part_a.py: the 2x2 contact experiment; part_b.py: friction and stopping; checkpoints.py: C1-C8;
hands_on.py: the hands-on exercise and the extension.
"""

from . import checkpoints, hands_on, part_a, part_b  # noqa: F401  (each module registers its checks)
from .scorer import (
    SCORING_RULES,
    LESSON_RUNS,
    RULE_READS,
    SHEET_CASE_PREFIX,
    ArchivedRubric,
    GradeReport,
    ItemGrade,
    Verdict,
    case_name,
    cases_to_run,
    lesson_run_specs,
    grade_sheet,
    runs_read,
)

__all__ = ["SCORING_RULES", "LESSON_RUNS", "SHEET_CASE_PREFIX", "ArchivedRubric", "GradeReport", "ItemGrade", "Verdict", "case_name",
           "cases_to_run", "lesson_run_specs", "grade_sheet", "RULE_READS", "runs_read"]
