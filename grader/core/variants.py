"""Variant pools in the neutral core (issue 34): the variant a submission is graded under, a pool variant's verdict
once its measuring submission's lab check lands, and the copy evidence stored when a variant sheet is graded.

The worker reaches these through grader.core.grading and worker.grading (it imports only the core); the set-up
service (grader.services.setup.variants) draws, stores and measures pools and assigns variants.
"""

from __future__ import annotations

import copy
import logging

from sqlalchemy import select
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

import rubric
from rubric.copying import copy_evidence

from grader.core.lifecycle import (COMPLETE_PRIORITY, NEW_PRIORITY, POOL_CHECK_PRIORITY, POOL_PRIORITY,
                                   reuse_at_admission, stored_result)
from grader.core.models import CaseRun, CopyFlag, Event, Grade, PoolVariant, Submission, User, VariantPool, utcnow
from grader.core.rubrics import course_rubric
from grader.core.states import CaseRunState, PoolState, VariantState
from grader.core.submissions import create_submission

log = logging.getLogger(__name__)


def as_variant(row: PoolVariant) -> rubric.Variant:
    """The rubric's Variant of a stored pool variant (its parameters as drawn, its id the pool's name for it)."""
    pool = row.pool
    return rubric.Variant(id=row.name, lesson=pool.lesson, space_version=pool.space_version,
                          space_hash=pool.space_hash, parameters=row.parameters)


def submission_variant(submission: Submission) -> rubric.Variant | None:
    """The variant a submission is graded under, read from its row; None: the lesson's shipped cases."""
    return as_variant(submission.variant) if submission.variant is not None else None


def measured_variant(session: Session, submission: Submission) -> PoolVariant | None:
    """The pool variant whose lesson runs this submission measures, or None for any other submission."""
    return session.scalar(select(PoolVariant).where(PoolVariant.submission_id == submission.id))


def measuring_submissions():
    """SQL: the ids of the submissions that measure a pool's variants (an instructor's, graded only to check the
    variant): not a student's work, left out of the grade exports."""
    return select(PoolVariant.submission_id).where(PoolVariant.submission_id.is_not(None))


def pool_runs(session: Session, case_run_ids) -> set[int]:
    """Of `case_run_ids`, the runs of a pool's measuring submissions: sent and re-sent at lifecycle.POOL_PRIORITY,
    behind every student's runs, whoever sends them (the pool's measuring, the reconciler, a person re-sending one)."""
    ids = list(case_run_ids)
    if not ids:
        return set()
    return set(session.scalars(select(CaseRun.id).where(CaseRun.id.in_(ids),
                                                        CaseRun.submission_id.in_(measuring_submissions()))))


def send_priority(session: Session, run: CaseRun, otherwise: int = NEW_PRIORITY) -> int:
    """The priority to send `run` at: POOL_PRIORITY for a pool's measuring run, else `otherwise`."""
    return POOL_PRIORITY if pool_runs(session, [run.id]) else otherwise


def completion_priority(session: Session, submission_id: int) -> int:
    """The priority to send a grade's completion (its lab check) at: POOL_CHECK_PRIORITY for a pool's measuring
    submission (ahead of every pool's runs), else COMPLETE_PRIORITY (behind every case)."""
    measuring = session.scalar(select(PoolVariant.id).where(PoolVariant.submission_id == submission_id))
    return POOL_CHECK_PRIORITY if measuring is not None else COMPLETE_PRIORITY


def decide(session: Session, row: PoolVariant, *, kept: bool, reason: str | None, check: dict | None = None) -> None:
    """Keep or drop a measuring variant (no commit); the pool is ready once none is left measuring."""
    row.state = VariantState.KEPT if kept else VariantState.DROPPED
    row.reason, row.check, row.decided_at = reason, check, utcnow()
    session.flush()
    pool = row.pool
    if pool.state != PoolState.READY and all(v.state in (VariantState.KEPT, VariantState.DROPPED)
                                             for v in pool.variants):
        pool.state, pool.ready_at = PoolState.READY, utcnow()


def draw_budget(pool: VariantPool) -> int:
    """The most variants `pool` may draw and measure to keep K (a pool from before issue 47: K)."""
    return pool.draw_budget if pool.draw_budget is not None else pool.k


def kept_count(pool: VariantPool) -> int:
    return sum(v.state == VariantState.KEPT for v in pool.variants)


def serves_students(pool: VariantPool) -> bool:
    """Whether students get a variant now: once `minimum` are kept (the pool may still be measuring more), or, for a
    pool without one, once nothing is left to measure and at least one is kept (as before issue 47)."""
    kept = kept_count(pool)
    if pool.minimum is not None:
        return kept >= pool.minimum
    return pool.state == PoolState.READY and kept > 0


def outcome(pool: VariantPool) -> str:
    """What the pool says about K: kept, still drawing, or its draw budget spent, in one sentence for staff."""
    kept, drawn, budget = kept_count(pool), len(pool.variants), draw_budget(pool)
    if pool.state != PoolState.READY:
        return f"measuring: {kept} of {pool.k} kept so far, {drawn} of at most {budget} variants drawn"
    if kept >= pool.k:
        return f"kept {kept} of the {pool.k} asked for, in {drawn} variants drawn"
    return (f"the draw budget is spent: kept {kept} of the {pool.k} asked for after {drawn} variants drawn (at most "
            f"{budget}); top up to draw more")


def _measuring_sheet(session: Session, pool: VariantPool, variant: rubric.Variant) -> dict | None:
    """A new variant's measuring sheet, made from one the pool already measured: the same answers, each config
    replaced by the new variant's case of the same name. None when none of the pool's variants was measured."""
    template = next((v.submission_id for v in pool.variants if v.submission_id is not None), None)
    if template is None:
        return None
    sheet = copy.deepcopy(session.get(Submission, template).sheet)
    cases = variant.cases()
    sheet["student"] = f"variant-{variant.id}"
    sheet["configs"] = {role: cases[config["name"]].model_dump(mode="json", exclude_computed_fields=True)
                        for role, config in (sheet.get("configs") or {}).items()}
    return sheet


def continue_pool(session: Session, submission_id: int) -> tuple[list[tuple[int, int, str]], list[int]]:
    """K means kept (issue 47): once a measuring submission's lab check landed, draw the pool further from its seed
    when it may no longer keep K (kept + still measuring < K) and its draw budget allows, and measure the new variants
    as the first were (each one measuring submission by the pool's creator). Commits. Returns what to send: the new
    case runs (id, delivery, backend), at lifecycle.POOL_PRIORITY, and the submissions whose runs were all stored
    already (their grade task). Nothing for any other submission. Sent by the worker (worker.tasks), which may send
    case runs as it re-sends a dead process's."""
    row = session.scalar(select(PoolVariant).where(PoolVariant.submission_id == submission_id))
    if row is None:
        return [], []
    pool = session.get(VariantPool, row.pool_id, with_for_update=True, populate_existing=True)
    session.refresh(pool, ["variants"])
    open_ = sum(v.state in (VariantState.DRAWN, VariantState.MEASURING) for v in pool.variants)
    short = pool.k - kept_count(pool) - open_
    room = draw_budget(pool) - len(pool.variants)
    if short <= 0 or room <= 0:
        session.rollback()
        return [], []
    space = rubric.load_variant_space(pool.lesson, pool.space_version)
    if space.content_hash != pool.space_hash:
        log.error("pool %s: variant space %s v%s changed since it was drawn; not drawn further", pool.id,
                  pool.lesson, pool.space_version)
        session.rollback()
        return [], []
    try:
        drawn = rubric.draw_pool(space, seed=pool.seed, k=len(pool.variants) + min(short, room)).variants
    except rubric.VariantPoolError as exc:  # the space holds no more: measure what it still gave
        drawn = exc.pool.variants
    book = course_rubric(session, pool.assignment.course_id, pool.lesson)
    creator = session.get(User, pool.created_by_id)
    runs, grades = [], []
    for position, variant in enumerate(drawn[len(pool.variants):], start=len(pool.variants) + 1):
        new = PoolVariant(pool_id=pool.id, name=variant.id, position=position, parameters=variant.parameters,
                          digest=variant.digest, state=VariantState.DRAWN)
        session.add(new)
        session.flush()
        sheet = _measuring_sheet(session, pool, variant)
        if sheet is None:  # nothing measured yet to make a sheet from: the instructor's top-up measures it
            continue
        specs = rubric.cases_to_run(rubric.parse_sheet(sheet), book, variant)
        submission = create_submission(session=session, student=creator, lesson=pool.lesson, sheet=sheet,
                                       specs=specs, force_rerun=False)
        submission.variant_id = new.id
        new.submission_id, new.state = submission.id, VariantState.MEASURING
        session.flush()
        if reuse_at_admission(session=session, submission=submission):
            grades.append(submission.id)
        runs += [(r.id, r.delivery, r.backend) for r in submission.case_runs if r.status == CaseRunState.QUEUED]
    pool.state, pool.ready_at = PoolState.MEASURING, None
    try:
        session.commit()
    except IntegrityError:  # drawn further meanwhile by another lab check landing: that one measures them
        session.rollback()
        return [], []
    return runs, grades


def drop_reason(check) -> str:
    """Why a variant whose lab check failed is dropped: each failed condition with its evidence."""
    failed = [c for c in check.conditions if not c.passed]
    return "lab check failed: " + "; ".join(f"{c.id} ({c.title}): {c.evidence.splitlines()[0] if c.evidence else ''}"
                                            for c in failed)


def record_check(session: Session, submission: Submission, check, note: str) -> None:
    """When `submission` measures a pool variant still measuring: keep it if its lab check passed, else drop it with
    the failed conditions as its reason (no commit). A check that could not be evaluated (None) drops it with `note`."""
    row = measured_variant(session, submission)
    if row is None or row.state != VariantState.MEASURING:
        return
    if check is None:
        decide(session, row, kept=False, reason=f"lab check not evaluated: {note}")
    elif check.passed:
        decide(session, row, kept=True, reason=None, check=check.model_dump(mode="json"))
    else:
        decide(session, row, kept=False, reason=drop_reason(check), check=check.model_dump(mode="json"))


def record_failure(session: Session, submission: Submission, error: str) -> None:
    """A measuring submission that could not be graded drops its variant with that error (no commit)."""
    row = measured_variant(session, submission)
    if row is not None and row.state == VariantState.MEASURING:
        decide(session, row, kept=False, reason=f"measurement failed: {error}")


def _dumped(spec) -> dict:
    return spec.model_dump(mode="json", exclude_computed_fields=True)


def runs_on(session: Session, other: PoolVariant, sheet, book, own: Submission) -> dict:
    """The stored runs grading `sheet` on variant `other` needs, without running anything: each case the sheet asks
    for under `other` (rubric.cases_to_run) taken from `other`'s measuring submission, else from the student's own runs,
    wherever one holds exactly that spec; a case neither holds is left out (graded not measured there)."""
    needed = {spec.name: _dumped(spec) for spec in rubric.cases_to_run(sheet, book, as_variant(other))}
    measuring = session.get(Submission, other.submission_id)
    results = {}
    for run in [*measuring.case_runs, *own.case_runs]:
        if run.name not in results and needed.get(run.name) == run.spec:
            results[run.name] = stored_result(run)
    return results


def flag_copying(session: Session, submission: Submission, grade: Grade, report, book) -> list[CopyFlag]:
    """Grade a variant submission's sheet on every other kept variant's stored runs (no case runs) and store the
    copy evidence (rubric.copying.copy_evidence) against `grade`; the grade itself is never changed. Nothing for a
    submission without a variant or one that measures a pool (no commit)."""
    row = submission.variant
    if row is None or measured_variant(session, submission) is not None:
        return []
    sheet = rubric.parse_sheet(submission.sheet, submission.part)
    others = {other.name: rubric.grade_sheet(sheet, runs_on(session, other, sheet, book, submission), book,
                                             as_variant(other))
              for other in row.pool.variants
              if other.id != row.id and other.state == VariantState.KEPT and other.submission_id is not None}
    by_name = {v.name: v for v in row.pool.variants}
    flags = []
    found = copy_evidence(report, others)
    for evidence in found:
        flag = CopyFlag(submission_id=submission.id, grade_id=grade.id, variant_id=by_name[evidence.variant].id,
                        items=evidence.items, own_expected=evidence.own_expected,
                        other_expected=evidence.other_expected, summary=evidence.describe())
        session.add(flag)
        flags.append(flag)
    return flags


def try_flag_copying(session: Session, submission: Submission, grade: Grade, report, book) -> None:
    """`flag_copying`, whose failure never blocks or changes a grade: it is logged and recorded as an event instead."""
    if submission.variant_id is None:
        return
    try:
        with session.begin_nested():
            flag_copying(session, submission, grade, report, book)
    except Exception as exc:  # noqa: BLE001 - copy evidence is for the instructor; the grade stands, the event says why
        log.exception("copy evidence of submission %s failed", submission.id)
        # a student reads their events: the type only, never a message that could name another variant's runs
        session.add(Event(submission_id=submission.id, state="copy-evidence",
                          detail=f"copy evidence not computed ({type(exc).__name__}); see the service log"))


__all__ = ["as_variant", "completion_priority", "continue_pool", "decide", "draw_budget", "drop_reason", "kept_count", "outcome",
           "serves_students", "flag_copying", "measured_variant", "measuring_submissions",
           "pool_runs", "runs_on", "record_check", "record_failure", "send_priority", "submission_variant",
           "try_flag_copying"]
