"""Provenance guards: a result measured on something other than what was asked for or what the rubric pins is a
provenance violation. It is kept with its evidence and audited, but never graded (rubric.scoring replaces it by a
failed result carrying the reason, so the items that need it say why)."""

from __future__ import annotations

from dataclasses import replace

from .results import CaseResult
from .rubrics import Rubric


def provenance_violation(result: CaseResult, rubric: Rubric) -> str | None:
    """Why `result` may not be graded under `rubric`, or None. Only ok results are judged: a failed one already is."""
    if not result.ok or result.provenance is None:
        return None
    p = result.provenance
    if p.actual_backend != p.requested_backend:
        return (f"provenance violation: requested backend {p.requested_backend} but the numbers came from "
                f"{p.actual_backend}; kept and excluded from grading")
    measured = p.versions.get("genesis", "unknown")
    if measured != rubric.engine_version:
        return (f"provenance violation: measured with Genesis {measured}, but rubric {rubric.lesson} "
                f"v{rubric.version} pins Genesis {rubric.engine_version}; kept and excluded from grading")
    return None


def gradable(results: dict[str, CaseResult], rubric: Rubric) -> dict[str, CaseResult]:
    """The results with every provenance violation turned into a failed result that says why (arrays kept)."""
    out = {}
    for name, result in results.items():
        reason = provenance_violation(result, rubric)
        out[name] = result if reason is None else replace(result, status="failed", error=reason, metrics=None)
    return out
