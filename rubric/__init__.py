"""Pure domain of the grader: lesson case specs, the baseline case table, trajectory metrics and scoring.

Imports numpy and pydantic only, never Genesis, torch, a database, Celery or a web framework.
"""

from .cases import BASELINE_CASES, CHECK_CASES, COLOR_SWAP, CONTACT_CASES, FRICTION_CASES, get_case, with_backend
from .friction import effective_pair_friction
from .metrics import (
    Alignment,
    ContactMetrics,
    FrictionMetrics,
    LaneMetrics,
    Stop,
    align,
    case_metrics,
    contact_metrics,
    lane_metrics,
    parse_metrics,
    separation_mask,
    sustained_stop,
)
from .results import CaseResult, Discretization, Provenance, expected_arrays, validate_arrays
from .specs import CaseSpec, ContactCase, FieldChange, FrictionCase, describe_errors, field_changes, parse_case

from .analysis import ClassAnalysis, class_analysis
from .discrepancy import (
    ArrayDiff,
    AuditTolerances,
    CaseComparison,
    MetricDiff,
    RelationCheck,
    compare_cases,
    compare_relations,
    load_audit_tolerances,
)
from .copying import CopyEvidence, copy_evidence, indistinct_pairs
from .exports import grades_csv, gradescope_results
from .governance import ReportChanges, RubricGovernanceError, publish_variant_space, publish_version, report_changes
from .one_factor import ConfigFinding
from .rubrics import Rubric, load_rubric
from .scoring import ArchivedRubric, GradeReport, ItemGrade
from .sheet import PredictionSheet
# A sheet is parsed, run and graded by the lesson it names (rubric.lesson: found by entry point), L03 or another.
from .lesson import parse_sheet

from .variants import (
    Variant,
    VariantPoolError,
    VariantSpace,
    draw_pool,
    load_variant_space,
    parameter_summary,
    shipped_variant,
    variant_cases,
    variant_space_for,
)


def cases_to_run(sheet, rubric: Rubric | None = None, variant: Variant | None = None) -> list:
    """Every case grading `sheet` needs, by its lesson's declaration (rubric.scoring.cases_to_run for L03)."""
    from .lesson import lesson

    return lesson(sheet.lesson).cases_to_run(sheet, rubric, variant)


def one_factor_findings(sheet, rubric: Rubric, variant: Variant | None = None) -> dict[str, ConfigFinding]:
    """Each submitted config compared with its rule's baseline, by the rubric's lesson (rubric.one_factor for L03)."""
    from .lesson import lesson

    return dict(lesson(rubric.lesson).config_findings(sheet, rubric, variant))


def grade_sheet(sheet, results, rubric: Rubric | None = None, variant: Variant | None = None) -> GradeReport:
    """The sheet graded on its measured runs, by its lesson's declaration (rubric.scoring.grade_sheet for L03)."""
    from .lesson import lesson

    return lesson(sheet.lesson).grade_sheet(sheet, results, rubric, variant)


__all__ = [
    "ArrayDiff",
    "AuditTolerances",
    "CaseComparison",
    "MetricDiff",
    "RelationCheck",
    "compare_cases",
    "compare_relations",
    "load_audit_tolerances",
    "ClassAnalysis",
    "class_analysis",
    "ArchivedRubric",
    "COLOR_SWAP",
    "Discretization",
    "FrictionMetrics",
    "case_metrics",
    "parse_metrics",
    "separation_mask",
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
    "CopyEvidence",
    "copy_evidence",
    "indistinct_pairs",
    "GradeReport",
    "ItemGrade",
    "PredictionSheet",
    "ReportChanges",
    "Rubric",
    "RubricGovernanceError",
    "cases_to_run",
    "grade_sheet",
    "grades_csv",
    "gradescope_results",
    "load_rubric",
    "one_factor_findings",
    "parse_sheet",
    "publish_variant_space",
    "publish_version",
    "report_changes",
    "Variant",
    "VariantPoolError",
    "VariantSpace",
    "draw_pool",
    "load_variant_space",
    "parameter_summary",
    "shipped_variant",
    "variant_cases",
    "variant_space_for",
]
