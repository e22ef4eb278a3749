"""Per-student lab variants of a lesson: the reviewed variant space, the deterministic pool draw, the variant's cases,
and the student-facing texts that name the variant's numbers. Pure, like the rest of rubric/.

A rubric version with no variant space (rubric.variants.variant_space_for returns None) grades as it always did, and
every function here given no variant (None) returns the lesson's shipped cases and texts.
"""

from .apply import CaseSet, InvalidVariant, complete_parameters, variant_cases
from .draw import SHIPPED_ID, Pool, RejectedDraw, Variant, VariantPoolError, draw_pool, parameters_digest, shipped_variant
from .parameters import PARAMETERS, Knob, fixed_quantities, shipped_parameters
from .space import (
    Constraint,
    ParameterSpace,
    Range,
    VariantSpace,
    load_variant_space,
    parse_variant_space,
    variant_space_for,
    variant_space_versions,
)
from .texts import answer_label, config_description, item_question, parameter_rows, parameter_summary, questions

__all__ = [
    "CaseSet",
    "Constraint",
    "InvalidVariant",
    "Knob",
    "PARAMETERS",
    "ParameterSpace",
    "Pool",
    "Range",
    "RejectedDraw",
    "SHIPPED_ID",
    "Variant",
    "VariantPoolError",
    "VariantSpace",
    "answer_label",
    "complete_parameters",
    "config_description",
    "draw_pool",
    "fixed_quantities",
    "item_question",
    "load_variant_space",
    "parameter_rows",
    "parameter_summary",
    "parameters_digest",
    "parse_variant_space",
    "questions",
    "shipped_parameters",
    "shipped_variant",
    "variant_cases",
    "variant_space_for",
    "variant_space_versions",
]
