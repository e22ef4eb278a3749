"""Pure domain of the grader: lesson case specs, the baseline case table, trajectory metrics and scoring.

Imports numpy and pydantic only, never Genesis, torch, a database, Celery or a web framework.
"""

from .cases import BASELINE_CASES, CHECK_CASES, CONTACT_CASES, FRICTION_CASES, get_case, with_backend
from .friction import effective_pair_friction
from .metrics import Alignment, ContactMetrics, LaneMetrics, Stop, align, contact_metrics, lane_metrics, sustained_stop
from .results import CaseResult, Provenance, expected_arrays, validate_arrays
from .specs import CaseSpec, ContactCase, FieldChange, FrictionCase, describe_errors, field_changes, parse_case

from .exports import grades_csv, gradescope_results
from .rubrics import RegradePreview, Rubric, RubricGovernanceError, load_rubric, publish_version, regrade_preview
from .scoring import GradeReport, ItemGrade, cases_to_run, grade_sheet
from .sheet import ConfigFinding, PredictionSheet, one_factor_findings, parse_sheet

__all__ = [
    "BASELINE_CASES",
    "CHECK_CASES",
    "CONTACT_CASES",
    "FRICTION_CASES",
    "Alignment",
    "CaseResult",
    "CaseSpec",
    "ContactCase",
    "ContactMetrics",
    "FieldChange",
    "FrictionCase",
    "LaneMetrics",
    "Provenance",
    "Stop",
    "align",
    "contact_metrics",
    "describe_errors",
    "effective_pair_friction",
    "expected_arrays",
    "field_changes",
    "get_case",
    "lane_metrics",
    "parse_case",
    "sustained_stop",
    "validate_arrays",
    "with_backend",
    "ConfigFinding",
    "GradeReport",
    "ItemGrade",
    "PredictionSheet",
    "RegradePreview",
    "Rubric",
    "RubricGovernanceError",
    "cases_to_run",
    "grade_sheet",
    "grades_csv",
    "gradescope_results",
    "load_rubric",
    "one_factor_findings",
    "parse_sheet",
    "publish_version",
    "regrade_preview",
]
