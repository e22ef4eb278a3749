"""An assignment's pool of per-student lab variants (issue 34): drawn by an instructor from a seed before the
assignment opens, measured by the workers (each variant's lesson runs as the case runs of one measuring submission,
reused by content key by every student on it), kept or dropped on its lab check (grader.core.variants.record_check),
and drawn further by the worker until K are kept or its draw budget is spent (grader.core.variants.continue_pool,
issue 47); variants may be added at any time (`top_up`); staff read the pool and the copy evidence stored at grading. Which variant a student works on:
grader.services.setup.student_variants.

What a pool costs is counted against the instructor and the course (issue 44): K at most settings.variant_pool_k_max,
and at most settings.variant_pools_measuring_per_instructor / _per_course pools measuring at once (refused with 429
and Retry-After past either). Its runs are sent, and re-sent, at lifecycle.POOL_PRIORITY, the lowest: a worker takes
one only when no student's run waits, so a student's next run waits at most for the pool runs already on a slot.
"""

from __future__ import annotations

import logging
from collections import Counter
from datetime import datetime
from pathlib import Path

import yaml
from pydantic import BaseModel, ValidationError
from sqlalchemy import func, or_, select
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

import rubric
from rubric.scoring import lesson_run_specs

from grader.core import lifecycle
from grader.core.models import (Assignment, CaseRun, CopyFlag, Course, PoolVariant, StudentVariant, Submission, User,
                                VariantPool, utcnow)
from grader.core.grades import current_grade
from grader.core.rubrics import course_rubric
from grader.core.settings import settings
from grader.core.states import CaseRunState, PoolState, VariantState
from grader.core.variants import as_variant, decide, draw_budget, outcome, serves_students
from grader.services.errors import Conflict, Invalid, NotFound, Refused
from grader.services.identity import access
from grader.services.sending import Sender
from grader.services.submissions.submit import create_submission

log = logging.getLogger(__name__)

K_DEFAULT, K_MAX = 16, 64
# The draw budget when the instructor states none: twice K (the shipped space keeps >= 75% of its draws, issue 47), and
# at most this many times K when they do.
BUDGET_FACTOR, BUDGET_FACTOR_MAX = 2, 4
# A pool refused while others are measuring: when to ask again (its page says how many of their runs remain).
BUSY_RETRY_AFTER_S = 60
# The answers a measuring submission carries (the lesson's reference sheet; its grade is never a student's). Its
# configs are the variant's own exercise and extension cases, so a student's config made from the variant's baseline
# reuses their measurement (grader/core/content_key.py).
REFERENCE_SHEET = Path(__file__).resolve().parents[3] / "examples" / "l03" / "reference.yaml"
CONFIG_CASES = {"table_exercise": "friction-table-0.30", "extension": "N5"}


class VariantRow(BaseModel):
    """One variant of a pool as staff see it: its parameters, state and, when dropped, why."""

    id: str
    position: int
    digest: str
    state: str
    reason: str | None
    parameters: dict[str, float | int]
    students: int
    measuring_submission: int | None
    check_passed: bool | None


class PoolRuns(BaseModel):
    """What measuring the pool costs, and where its case runs are: all its measuring submissions' runs, how many wait
    in a queue, run now or finished, how many a stored measurement covered (nothing ran), the case time those that
    ran took so far, and the priority they wait at (lifecycle.POOL_PRIORITY: behind every student's runs)."""

    total: int
    queued: int
    running: int
    finished: int
    reused: int
    case_s: float
    priority: int


class PoolView(BaseModel):
    assignment_id: int
    lesson: str
    space_version: str
    space_hash: str
    rubric_version: str
    seed: int
    k: int
    draw_budget: int
    minimum: int | None
    drawn: int
    outcome: str
    serving: bool
    state: str
    kept: int
    dropped: int
    created_by: str
    created_at: datetime
    ready_at: datetime | None
    rejected_draws: dict[str, int]
    runs: PoolRuns
    variants: list[VariantRow]
    # Pairs of kept variants that no measured item tells apart (rubric.indistinct_pairs over their measuring
    # submissions' grades): copying between the two of a pair cannot be seen (issue 47)
    indistinct: list[tuple[str, str]] = []


class FlagRow(BaseModel):
    """One piece of copy evidence: whose submission, which other variant its answers fit, on which items."""

    submission_id: int
    student: str
    own_variant: str
    fits_variant: str
    items: list[str]
    own_expected: dict[str, str]
    other_expected: dict[str, str]
    summary: str
    created_at: datetime


def pool_of(session: Session, assignment: Assignment) -> VariantPool | None:
    return session.scalar(select(VariantPool).where(VariantPool.assignment_id == assignment.id))


def k_max() -> int:
    """The most variants a pool may ask for here: the variant space's K_MAX, or less (settings.variant_pool_k_max)."""
    return min(K_MAX, settings.variant_pool_k_max)


def _refuse_past_measuring_caps(session: Session, course_id: int, user: User) -> None:
    """Refused (429, Retry-After) while the instructor or the course has as many pools measuring as
    settings.variant_pools_measuring_per_instructor / _per_course allow. The course's row is locked first (PostgreSQL),
    so two pools asked for at once are counted one after the other; the caller commits."""
    session.get(Course, course_id, with_for_update=True)
    measuring = (select(VariantPool).join(Assignment, VariantPool.assignment_id == Assignment.id)
                 .where(Assignment.course_id == course_id, VariantPool.state == PoolState.MEASURING))
    mine = measuring.where(or_(VariantPool.created_by_id == user.id, VariantPool.id.in_(
        select(PoolVariant.pool_id).join(Submission, PoolVariant.submission_id == Submission.id)
        .where(Submission.student_id == user.id, PoolVariant.state == VariantState.MEASURING))))
    for query, limit, setting, whose in (
            (mine, settings.variant_pools_measuring_per_instructor, "variant_pools_measuring_per_instructor",
             "instructor"),
            (measuring, settings.variant_pools_measuring_per_course, "variant_pools_measuring_per_course", "course")):
        busy = session.scalars(query.order_by(VariantPool.id)).all()
        if len(busy) >= limit:
            titles = ", ".join(f"“{p.assignment.title}”" for p in busy)
            rule = (f"at most {limit} variant pool{'s' if limit != 1 else ''} measured at once per {whose} "
                    f"({setting}); still measuring: {titles}. Generate this one once "
                    f"{'it is' if len(busy) == 1 else 'one is'} ready")
            raise Refused("assignment", rule, BUSY_RETRY_AFTER_S, detail="variant pool refused",
                          reason=f"pools_measuring_{whose}", facts={"limit": limit, "setting": setting,
                                                                   "measuring": [p.assignment.title for p in busy]})


def _space_for(session: Session, assignment: Assignment, version: str | None = None):
    """The course's rubric and the variant space a new pool draws from: `version` if given (one reviewed for that
    rubric version), else the latest reviewed for it."""
    book = course_rubric(session, assignment.course_id, assignment.lesson)
    if version is not None:
        known = space_versions(session=session, assignment=assignment)
        if version not in known:
            raise Invalid("no such variant space", [{"field": "space_version", "rule": (
                f"one of the {assignment.lesson} variant spaces reviewed for rubric v{book.version}: "
                f"{', '.join(known) or 'none'}")}])
        return book, rubric.load_variant_space(assignment.lesson, version)
    space = rubric.variant_space_for(book) if isinstance(book, rubric.Rubric) else None
    if space is None:
        raise Invalid("no variant space", [{"field": "assignment", "rule": (
            f"the course grades {assignment.lesson} under rubric v{book.version}, which has no reviewed variant "
            "space (rubric/lessons/*-lab-variants-*.yaml): its students all work on the lesson's shipped cases")}],
                      reason="no_space", facts={"lesson": assignment.lesson, "version": str(book.version)})
    return book, space


def space_versions(*, session: Session, assignment: Assignment) -> list[str]:
    """The variant space versions a new pool of `assignment` may draw from (reviewed for the course's rubric version),
    oldest first; the last is the default."""
    book = course_rubric(session, assignment.course_id, assignment.lesson)
    return [v for v in rubric.variants.variant_space_versions(assignment.lesson)
            if rubric.load_variant_space(assignment.lesson, v).grading_rubric == str(book.version)]


def generate(*, session: Session, assignment: Assignment, user: User, seed: int, k: int = K_DEFAULT,
             budget: int | None = None, minimum: int | None = None, space_version: str | None = None) -> VariantPool:
    """Store a pool that keeps `k` variants of `assignment` (issue 47: K means kept): the first `k` drawn from `seed`
    (deterministic: rubric.draw_pool), each 'drawn' until `measure` sends its runs, and drawn further as variants are
    dropped (grader.core.variants.continue_pool) until K are kept or `budget` variants were drawn (default
    BUDGET_FACTOR x K); students get one once `minimum` are kept (default: once the pool is ready). The space is the
    latest reviewed for the course's rubric version, or `space_version` (one reviewed for it). Commits.
    Instructors of the course only; refused once the assignment has opened, while it has a pool already (one pool per
    assignment: its variants may be some student's), for a rubric version without a variant space, past k_max(), a
    budget outside K..BUDGET_FACTOR_MAX x K or a minimum outside 1..K (422), and while the instructor or the course has
    as many pools measuring as the settings allow (429: _refuse_past_measuring_caps)."""
    access.require_course_instructor(user, assignment.course_id, action="generate a variant pool",
                                     thing="assignment")
    rules = []
    if not 1 <= k <= k_max():
        rules.append({"field": "k", "rule": f"between 1 and {k_max()} variants" + (
            " (this service's limit, variant_pool_k_max)" if k_max() < K_MAX else "")})
    if not 0 <= seed < 2**31:
        rules.append({"field": "seed", "rule": "a whole number from 0 to 2147483647"})
    if budget is not None and not k <= budget <= BUDGET_FACTOR_MAX * k:
        rules.append({"field": "budget", "rule": f"between K ({k}) and {BUDGET_FACTOR_MAX} x K ({BUDGET_FACTOR_MAX * k}) "
                                                 "variants drawn"})
    if minimum is not None and not 1 <= minimum <= k:
        rules.append({"field": "minimum", "rule": f"between 1 and K ({k}) variants kept before students get one"})
    if rules:
        raise Invalid("invalid pool", rules)
    if utcnow() >= assignment.open_at:
        raise Conflict("the assignment has opened", [{"field": "assignment", "rule": (
            f"a pool is generated before the assignment opens ({assignment.open_at:%Y-%m-%d %H:%M} UTC): students "
            "already working on it would change lab")}], reason="pool_opened",
                       facts={"assignment": assignment.title, "at": assignment.open_at})
    existing = pool_of(session, assignment)
    if existing is not None:
        taken = session.scalar(select(func.count()).select_from(StudentVariant)
                               .where(StudentVariant.assignment_id == assignment.id))
        raise Conflict("the assignment has a pool", [{"field": "assignment", "rule": (
            f"assignment {assignment.id} has a pool already (seed {existing.seed}, {existing.k} variant"
            + ("" if existing.k == 1 else "s") + (f", {taken} student{'' if taken == 1 else 's'} on them" if taken else "")
            + "); an assignment keeps one pool")}],
                       reason="pool_exists", facts={"assignment": assignment.title, "seed": existing.seed,
                                                    "k": existing.k, "students": taken})
    book, space = _space_for(session, assignment, space_version)
    _refuse_past_measuring_caps(session, assignment.course_id, user)
    try:
        drawn = rubric.draw_pool(space, seed=seed, k=k)
    except rubric.VariantPoolError as exc:
        raise Invalid("the variant space cannot yield this pool", [{"field": "k", "rule": str(exc)}]) from None
    pool = VariantPool(assignment_id=assignment.id, lesson=assignment.lesson, space_version=space.version,
                       space_hash=space.content_hash, rubric_version=str(book.version), seed=seed, k=k,
                       draw_budget=budget if budget is not None else BUDGET_FACTOR * k, minimum=minimum,
                       state=PoolState.MEASURING, rejected=[r.model_dump(mode="json") for r in drawn.rejected],
                       created_by_id=user.id)
    session.add(pool)
    session.flush()
    for position, variant in enumerate(drawn.variants, start=1):
        session.add(PoolVariant(pool_id=pool.id, name=variant.id, position=position, parameters=variant.parameters,
                                digest=variant.digest, state=VariantState.DRAWN))
    try:
        session.commit()
    except IntegrityError:  # a concurrent generate won the assignment's one pool
        session.rollback()
        raise Conflict("the assignment has a pool", [{"field": "assignment",
                                                      "rule": "another pool was generated meanwhile"}]) from None
    session.refresh(pool)
    return pool


def screen(row: PoolVariant, space) -> list[str]:
    """Why a stored variant may not be measured: its parameters are not the lesson's, break a constraint of the pool's
    space, or build a case the schema refuses. Empty when it may."""
    try:
        variant = as_variant(row)
    except ValidationError as exc:
        return [f"parameters: {line}" for line in rubric.describe_errors(exc)]
    varying = {name: variant.parameters[name] for name in space.parameters}
    problems = [f"constraint {violation}" for violation in space.violations(varying)]
    try:
        rubric.variant_cases(variant.parameters)
    except rubric.InvalidVariant as exc:
        problems += [f"invalid case: {p}" for p in exc.problems]
    return problems


def measuring_sheet(variant: rubric.Variant) -> dict:
    """A measuring submission's sheet: the reference answers, the variant's exercise and extension cases as configs."""
    sheet = yaml.safe_load(REFERENCE_SHEET.read_text())
    cases = variant.cases()
    sheet["student"] = f"variant-{variant.id}"
    sheet["configs"] = {role: cases[name].model_dump(mode="json", exclude_computed_fields=True)
                        for role, name in CONFIG_CASES.items()}
    return sheet


def measure(*, session: Session, pool: VariantPool, user: User, sender: Sender) -> list[PoolVariant]:
    """Screen every drawn variant of `pool` (a broken one is dropped with its reason, nothing run) and queue the
    others' lesson runs, each variant as one measuring submission by `user` under that variant; what a stored
    measurement covers is reused at once. Commits, then sends. The variants are kept or dropped as their lab checks
    land (grader.core.variants.record_check, in the worker). Returns the variants now measuring."""
    access.require_course_instructor(user, pool.assignment.course_id, action="measure a variant pool",
                                     thing="assignment")
    space = rubric.load_variant_space(pool.lesson, pool.space_version)
    if space.content_hash != pool.space_hash:
        raise Conflict("the variant space changed", [{"field": "space_version", "rule": (
            f"{pool.lesson} variant space v{pool.space_version} no longer has the content this pool was drawn from")}])
    book = course_rubric(session, pool.assignment.course_id, pool.lesson)
    measuring, to_grade, to_send = [], [], []
    for row in pool.variants:
        if row.state != VariantState.DRAWN:
            continue
        problems = screen(row, space)
        if problems:
            row.state = VariantState.MEASURING
            decide(session, row, kept=False, reason="parameters refused before measuring: " + "; ".join(problems))
            continue
        variant = as_variant(row)
        sheet = measuring_sheet(variant)
        specs = rubric.cases_to_run(rubric.parse_sheet(sheet), book, variant)
        submission = create_submission(session=session, student=user, lesson=pool.lesson, sheet=sheet, specs=specs,
                                       force_rerun=False)
        submission.variant_id = row.id
        row.submission_id, row.state = submission.id, VariantState.MEASURING
        session.flush()
        if lifecycle.reuse_at_admission(session=session, submission=submission):
            to_grade.append(submission.id)
        to_send += [run for run in submission.case_runs if run.status == CaseRunState.QUEUED]
        measuring.append(row)
    session.commit()
    for submission_id in to_grade:
        try:
            sender.send_grade(submission_id)
        except Exception:  # stored as 'grading': the reconciler re-sends its grade task
            log.exception("could not enqueue the grading of measuring submission %s", submission_id)
    for run in to_send:
        try:
            sender.send_case_run(run.id, run.delivery, run.backend, priority=lifecycle.POOL_PRIORITY)
        except Exception:  # stored and queued: the reconciler re-sends it
            log.exception("could not enqueue case run %s of a variant pool", run.id)
    return measuring


def generate_and_measure(*, session: Session, assignment: Assignment, user: User, seed: int, k: int = K_DEFAULT,
                         budget: int | None = None, minimum: int | None = None, space_version: str | None = None,
                         sender: Sender) -> VariantPool:
    """`generate` then `measure`: what the API and the command line do."""
    pool = generate(session=session, assignment=assignment, user=user, seed=seed, k=k, budget=budget, minimum=minimum,
                    space_version=space_version)
    measure(session=session, pool=pool, user=user, sender=sender)
    session.refresh(pool)
    return pool


def top_up(*, session: Session, assignment: Assignment, user: User, sender: Sender,
           more: int | None = None) -> list[PoolVariant]:
    """Draw the pool further from its seed (the seed's next draws: the pool stays reproducible) and measure the new
    variants like the first. At any time (issue 47): students who have a variant keep it, and new students are spread
    over every kept variant (grader.services.setup.student_variants). With `more`, K grows by `more` (and the draw
    budget by BUDGET_FACTOR x `more`); without, a ready pool that kept fewer than K (its budget spent) draws the
    K - kept it lacks, its budget raised by as many. Instructors of the course only, within the caps on pools measuring
    at once (as `generate`); without `more`, refused while it is still measuring or keeps K already. Returns the
    variants added."""
    access.require_course_instructor(user, assignment.course_id, action="draw a variant pool further",
                                     thing="assignment")
    pool = pool_of(session, assignment)
    if pool is None:
        raise NotFound(f"assignment {assignment.id} has no variant pool")
    if more is not None and not 1 <= more <= k_max():
        raise Invalid("invalid top-up", [{"field": "more", "rule": f"between 1 and {k_max()} variants more to keep"}])
    kept = sum(v.state == VariantState.KEPT for v in pool.variants)
    rule = why = None  # `why` names the rule for a page to word it (grader/templates/setup/assignments.html)
    if more is None and pool.state != PoolState.READY:
        rule, why = "its variants are still being measured: top up once every one is kept or dropped", "measuring"
    elif more is None and kept >= pool.k:
        rule, why = f"it keeps {kept} of the {pool.k} variants asked for already", "full"
    if rule is not None:
        raise Conflict("the pool is not drawn further", [{"field": "assignment", "rule": rule}],
                       reason=f"top_up_{why}", facts={"assignment": assignment.title, "kept": kept, "k": pool.k,
                                                      "at": assignment.open_at})
    _refuse_past_measuring_caps(session, assignment.course_id, user)
    space = rubric.load_variant_space(pool.lesson, pool.space_version)
    drawn_so_far = len(pool.variants)
    wanted = more if more is not None else pool.k - kept
    try:
        drawn = rubric.draw_pool(space, seed=pool.seed, k=drawn_so_far + wanted)
    except rubric.VariantPoolError as exc:
        raise Invalid("the variant space cannot yield more variants", [{"field": "k", "rule": str(exc)}]) from None
    added = [PoolVariant(pool_id=pool.id, name=v.id, position=drawn_so_far + n, parameters=v.parameters,
                         digest=v.digest, state=VariantState.DRAWN)
             for n, v in enumerate(drawn.variants[drawn_so_far:], start=1)]
    session.add_all(added)
    budget = draw_budget(pool)
    if more is not None:
        if pool.minimum is None and serves_students(pool):
            pool.minimum = kept  # students kept being served while the new variants are measured
        pool.k += more
        pool.draw_budget = max(budget, drawn_so_far) + BUDGET_FACTOR * more
    else:
        pool.draw_budget = max(budget, drawn_so_far) + wanted
    pool.state, pool.ready_at = PoolState.MEASURING, None
    session.commit()
    session.refresh(pool)
    measure(session=session, pool=pool, user=user, sender=sender)
    return added


def pool_view(*, session: Session, assignment: Assignment, user: User) -> PoolView | None:
    """The pool with every variant's parameters, state and reason: staff of the course only (a student never reads
    another variant's parameters). None when the assignment has no pool (its students work on the shipped lab)."""
    if user.course_id != assignment.course_id:
        raise NotFound("assignment not found")
    access.require_staff(user, action="read a variant pool")
    pool = pool_of(session, assignment)
    if pool is None:
        return None
    students = Counter(session.scalars(select(StudentVariant.variant_id)
                                       .where(StudentVariant.assignment_id == assignment.id)).all())
    rows = [VariantRow(id=v.name, position=v.position, digest=v.digest, state=v.state, reason=v.reason,
                       parameters=v.parameters, students=students.get(v.id, 0), measuring_submission=v.submission_id,
                       check_passed=(v.check or {}).get("passed") if v.check else None) for v in pool.variants]
    creator = session.get(User, pool.created_by_id)
    runs = _runs_of(session, [v.submission_id for v in pool.variants if v.submission_id is not None])
    return PoolView(assignment_id=assignment.id, lesson=pool.lesson, space_version=pool.space_version,
                    space_hash=pool.space_hash, rubric_version=pool.rubric_version, seed=pool.seed, k=pool.k,
                    draw_budget=draw_budget(pool), minimum=pool.minimum, drawn=len(pool.variants),
                    outcome=outcome(pool), serving=serves_students(pool), state=pool.state, kept=sum(r.state == VariantState.KEPT for r in rows),
                    dropped=sum(r.state == VariantState.DROPPED for r in rows), created_by=creator.name,
                    created_at=pool.created_at, ready_at=pool.ready_at,
                    rejected_draws=dict(Counter(reason.split(":")[0] for r in pool.rejected for reason in r["reasons"])),
                    runs=runs, variants=rows, indistinct=_indistinct(session, pool))


def _indistinct(session: Session, pool: VariantPool) -> list[tuple[str, str]]:
    """rubric.indistinct_pairs over the kept variants' measuring grades (each the lesson's sheet graded on that
    variant's own runs, so its expected answers are the variant's), in the pool's order."""
    reports = {}
    for row in sorted(pool.variants, key=lambda v: v.position):
        if row.state == VariantState.KEPT and row.submission_id is not None:
            grade = current_grade(session, row.submission_id)
            if grade is not None:
                reports[row.name] = rubric.GradeReport.model_validate(grade.report)
    return rubric.indistinct_pairs(reports)


def _runs_of(session: Session, submission_ids: list[int]) -> PoolRuns:
    """PoolRuns of the pool's measuring submissions."""
    by_state, reused, case_s = Counter(), 0, 0.0
    if submission_ids:
        for status, was_reused, n, wall in session.execute(
                select(CaseRun.status, CaseRun.reused_from_id.is_not(None), func.count(), func.sum(CaseRun.wall_s))
                .where(CaseRun.submission_id.in_(submission_ids)).group_by(CaseRun.status,
                                                                           CaseRun.reused_from_id.is_not(None))):
            by_state[status] += n
            reused += n if was_reused else 0
            case_s += float(wall or 0.0) if not was_reused else 0.0
    waiting = (CaseRunState.QUEUED, CaseRunState.RUNNING)
    return PoolRuns(total=sum(by_state.values()), queued=by_state[CaseRunState.QUEUED],
                    running=by_state[CaseRunState.RUNNING],
                    finished=sum(n for status, n in by_state.items() if status not in waiting), reused=reused,
                    case_s=round(case_s, 1), priority=lifecycle.POOL_PRIORITY)


def copy_flags(*, session: Session, assignment: Assignment, user: User) -> list[FlagRow]:
    """The copy evidence stored for the assignment's graded submissions, newest first: staff of the course only."""
    if user.course_id != assignment.course_id:
        raise NotFound("assignment not found")
    access.require_staff(user, action="read copy evidence")
    flags = session.scalars(select(CopyFlag).join(Submission, CopyFlag.submission_id == Submission.id)
                            .where(Submission.assignment_id == assignment.id)
                            .order_by(CopyFlag.id.desc())).all()
    return [FlagRow(submission_id=f.submission_id, student=f.submission.student.name,
                    own_variant=f.submission.variant.name if f.submission.variant else "",
                    fits_variant=f.variant.name, items=f.items, own_expected=f.own_expected,
                    other_expected=f.other_expected, summary=f.summary, created_at=f.created_at) for f in flags]
