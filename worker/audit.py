"""The backend-discrepancy audit, worker side: after a case run finishes, compare it with every other measurement of
the same case that differs in backend, precision or execution mode, and append an entry to the audit log.

Entries are append-only (the database refuses UPDATE and DELETE), so everything an entry shows, figures included,
is made before it is inserted. An audit re-run (purpose "audit") is compared with the run it re-measures; a run
that broke provenance (another backend than requested, another engine than the rubric pins) gets an entry of its
own. Comparing never changes a grade.
"""

from __future__ import annotations

import logging
from pathlib import Path

from sqlalchemy import select
from sqlalchemy.orm import Session

from rubric import CaseResult, Provenance, parse_case
from rubric.discrepancy import compare_cases, compare_relations, summarize
from rubric.guards import provenance_violation

from grader.core.audit import PROVENANCE_MARKERS, spec_key, variant
from grader.core.lifecycle import stored_result
from grader.core.rubrics import course_rubric
from grader.core.models import AuditEntry, CaseRun
from grader.core.settings import settings
from grader.core.states import TERMINAL, CaseRunState

log = logging.getLogger(__name__)


def audit_finished_run(session: Session, run_id: int) -> list[AuditEntry]:
    """Every audit entry the finished run calls for (commits); never raises for a comparison's own failure."""
    run = session.get(CaseRun, run_id)
    if run is None or run.status not in TERMINAL:
        return []
    if run.spec_key is None:
        run.spec_key = spec_key(run.spec)
        session.commit()
    entries = []
    try:
        if run.purpose == "audit" and run.source_case_run_id is not None:
            entries.append(_entry(session, session.get(CaseRun, run.source_case_run_id), run,
                                  requested_by_id=run.requested_by_id))
        elif _provenance_violation(run):
            entries.append(_violation_entry(session, run, run.error))
        elif (reason := _pin_violation(session, run)) is not None:
            entries.append(_violation_entry(session, run, reason))
        elif run.status == CaseRunState.DONE and run.reused_from_id is None:
            for other in _other_variants(session, run):
                entries.append(_entry(session, other, run))
    except Exception:  # noqa: BLE001 - the audit must never lose the run or its grade; the log names it
        session.rollback()
        log.exception("audit of case run %s failed", run_id)
        return []
    session.commit()
    return entries


def _provenance_violation(run: CaseRun) -> bool:
    return run.status == CaseRunState.FAILED and any(m in (run.error or "") for m in PROVENANCE_MARKERS)


def _pin_violation(session: Session, run: CaseRun) -> str | None:
    """A finished run whose provenance breaks what its course's rubric pins (rubric.guards), or None."""
    if run.status != CaseRunState.DONE or run.reused_from_id is not None or not run.provenance:
        return None
    result = CaseResult(spec=parse_case(run.spec), status="ok", provenance=Provenance.model_validate(run.provenance))
    return provenance_violation(result, course_rubric(session, run.submission.course_id, run.submission.lesson))


def _other_variants(session: Session, run: CaseRun) -> list[CaseRun]:
    """One measured run per other variant of the same case, skipping pairs already in the log."""
    mine = variant(run)
    seen = {mine}
    logged = {frozenset((e.left_variant, e.right_variant)) for e in session.scalars(
        select(AuditEntry).where(AuditEntry.spec_key == run.spec_key))}
    found = []
    for other in session.scalars(select(CaseRun).where(
            CaseRun.spec_key == run.spec_key, CaseRun.id != run.id, CaseRun.status == CaseRunState.DONE,
            CaseRun.result_status == "ok", CaseRun.reused_from_id.is_(None)).order_by(CaseRun.id)):
        theirs = variant(other)
        if theirs in seen or frozenset((mine, theirs)) in logged:
            continue
        seen.add(theirs)
        found.append(other)
    return found


def _course_of(run: CaseRun) -> int | None:
    return run.submission.course_id if run.submission is not None else None


def _entry(session: Session, left: CaseRun, right: CaseRun, *, requested_by_id: int | None = None) -> AuditEntry:
    base = dict(course_id=_course_of(left), lesson=left.submission.lesson, case=left.name, spec_key=left.spec_key
                or spec_key(left.spec), spec=left.spec, left_case_run_id=left.id, right_case_run_id=right.id,
                left_variant=variant(left), right_variant=variant(right), left_provenance=left.provenance,
                right_provenance=right.provenance, requested_by_id=requested_by_id, figures=[])
    a, b = stored_result(left), stored_result(right)
    if not (a.ok and b.ok):
        failed = [f"case run {r.id} ({variant(r)}): {r.error or r.status}" for r in (left, right)
                  if r.status != CaseRunState.DONE or r.result_status != "ok"]
        return _add(session, AuditEntry(**base, classification="not_compared", comparison=None,
                                        summary="not compared: " + "; ".join(failed)))
    comparison = with_set_relations(compare_cases(a, b), *(_variant_set(session, r) for r in (left, right)))
    folder = Path(settings.artifacts_dir) / "audit" / f"{left.id}-{right.id}-{right.delivery}"
    figures = _draw(a, b, comparison, folder)
    return _add(session, AuditEntry(**base | {"figures": figures}, classification=comparison.classification,
                                    summary=comparison.summary, comparison=comparison.model_dump(mode="json"),
                                    figures_dir=str(folder)))


def _variant_set(session: Session, run: CaseRun) -> dict:
    """Every measured case of `run`'s submission in `run`'s variant, by lesson case name (an audit re-run stands for
    the case it re-measures), so the lesson's relations between cases can be judged on each side."""
    submission = run.submission
    wanted, found = variant(run), {}
    for other in submission.case_runs:
        if other.status == CaseRunState.DONE and other.result_status == "ok" and variant(other) == wanted:
            found[other.name] = other
    for other in submission.audit_runs:
        source = session.get(CaseRun, other.source_case_run_id) if other.source_case_run_id else None
        if source is not None and other.status == CaseRunState.DONE and other.result_status == "ok" and variant(other) == wanted:
            found[source.name] = other
    return {name: stored_result(r) for name, r in found.items()}


def with_set_relations(comparison, left: dict, right: dict):
    """The comparison with the lesson's relations between cases that both variants can now judge (rubric.discrepancy
    compare_relations) added; a relation that changed makes the entry relation_changed."""
    extra = [r for r in compare_relations(left, right) if r.id not in {x.id for x in comparison.relations}]
    if not extra:
        return comparison
    relations = [*comparison.relations, *extra]
    classification = "relation_changed" if any(r.changed for r in relations) else comparison.classification
    updated = comparison.model_copy(update={"relations": relations, "classification": classification})
    return updated.model_copy(update={"summary": summarize(updated)})


def _violation_entry(session: Session, run: CaseRun, reason: str | None) -> AuditEntry:
    return _add(session, AuditEntry(
        course_id=_course_of(run), lesson=run.submission.lesson, case=run.name, spec_key=run.spec_key, spec=run.spec,
        left_case_run_id=run.id, right_case_run_id=None, left_variant=variant(run),
        right_variant=f"requested {run.backend}/{run.precision}", left_provenance=run.provenance,
        right_provenance=None, classification="provenance_violation", comparison=None, figures=[],
        summary=reason if reason and "excluded from grading" in reason else f"kept and excluded from grading: {reason}"))


def _draw(a, b, comparison, folder: Path) -> list[str]:
    # lazy: matplotlib (~0.7 s) loads only when an audit draws, not in every Celery worker (bench memory target)
    from worker.figures import draw_comparison

    try:
        return [p.name for p in draw_comparison(a, b, comparison, folder)]
    except Exception:  # noqa: BLE001 - a drawing bug leaves an entry without figures, never no entry
        log.exception("audit figures for %s failed", folder)
        return []


def _add(session: Session, entry: AuditEntry) -> AuditEntry:
    session.add(entry)
    session.flush()
    return entry
