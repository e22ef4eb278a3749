"""Regrade a course's lesson under another rubric version: preview per student (nothing written), then commit.

The regrade reads the measurements already stored with each submission's case runs, never runs a case: which
cases a sheet needs is decided by the lesson and the sheet's configs (rubric.cases_to_run), and a submission whose
new version needs a case it never measured is left on its grade with that reason. Committing supersedes each
current grade with a new one under the new version and keeps the old (grader.core.grades.grade_history), and the
course grades its new submissions under that version from then on. Both are recorded with who and when.

An instructor's override (grader.services.submissions.overrides) outlives a regrade: the new grade applies the submission's current
overrides to what the new version measures, and the preview says so per student and item (`overrides`).

A course regrades only under the versions it may read (shipped, or its own published ones), and a commit names the
content hash its preview showed: content other than what the instructor previewed is never committed.
"""

from __future__ import annotations

import re
import time

from pydantic import BaseModel
from sqlalchemy import select
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

import rubric
from grader.core import grading
from grader.core.lab_check import lab_check
from grader.core.lifecycle import stored_result
from grader.core.variants import submission_variant
from grader.core.rubrics import course_version, course_versions, get_version, stored_version
from grader.core.models import Course, Grade, Regrade, RubricVersion, Submission, User, utcnow
from grader.core.schemas import UtcDateTime
from grader.services.errors import Conflict, Invalid, NotFound
from grader.services.submissions.overrides import current_overrides, overridden_report
from grader.core.settings import settings
from rubric import ArchivedRubric
from rubric.governance import report_changes, rubric_changes
from rubric.rubrics import VERSION_PATTERN
from rubric.scoring.scorer import ensure_gradable

LESSON_PATTERN = r"^L[0-9]{2}$"
HASH_PATTERN = r"^[0-9a-f]{64}$"
RULES = {"lesson": LESSON_PATTERN, "version": VERSION_PATTERN, "content_hash": HASH_PATTERN}
MAX_LENGTH = {"lesson": 3, "version": 32, "content_hash": 64}


class ItemDiff(BaseModel):
    id: str
    old_score: float | None
    new_score: float | None
    old_verdict: str | None
    new_verdict: str | None
    why: str  # the rubric change behind it, and what the new version's check says


class RegradeEntry(BaseModel):
    submission_id: int
    student: str
    old_version: str
    new_version: str
    old_total: float
    new_total: float | None
    max_total: float | None
    changed_items: list[ItemDiff]
    skipped: str | None = None  # why this submission stays on its old grade
    overrides: list[str] = []  # each override the new grade keeps (or drops), with what the new version measures

    @property
    def delta(self) -> float | None:
        return None if self.new_total is None else self.new_total - self.old_total


class RegradePreview(BaseModel):
    course: str
    lesson: str
    current_version: str
    new_version: str
    content_hash: str  # of the new version's content: a commit names it, and is refused if it changed
    rubric_changes: dict[str, list[str]]  # per old version: what differs in the new one
    entries: list[RegradeEntry]
    elapsed_s: float

    @property
    def changed(self) -> list[RegradeEntry]:
        return [e for e in self.entries if e.skipped is None and (e.changed_items or e.delta)]


class RegradeRecord(BaseModel):
    id: int
    course: str
    lesson: str
    version: str
    committed_by: str
    committed_at: UtcDateTime
    regraded: int
    changed: int
    skipped: list[dict]


def record(row: Regrade, course: Course) -> RegradeRecord:
    return RegradeRecord(id=row.id, course=course.name, lesson=row.lesson, version=row.version,
                         committed_by=row.committed_by.name, committed_at=row.committed_at, regraded=row.regraded,
                         changed=row.changed, skipped=row.skipped)


def _graded(session: Session, course: Course, lesson: str) -> list[tuple[Submission, Grade]]:
    return [(s, g) for s, g in session.execute(
        select(Submission, Grade).join(Grade, Grade.submission_id == Submission.id)
        .where(Submission.course_id == course.id, Submission.lesson == lesson, Grade.superseded_at.is_(None))
        .order_by(Submission.id))]


def _why(item_id: str, old_rubric, new_rubric, new_item) -> str:
    reasons = []
    old_def = next((i for i in old_rubric.items if i.id == item_id), None)
    new_def = next((i for i in new_rubric.items if i.id == item_id), None)
    if old_def is None or new_def is None:
        reasons.append("item added in the new version" if old_def is None else "item removed in the new version")
    else:
        if old_def.points != new_def.points:
            reasons.append(f"points {old_def.points:g} -> {new_def.points:g}")
        for name in new_def.tolerances:
            a, b = old_rubric.tolerances.get(name), new_rubric.tolerances.get(name)
            if b is not None and (a is None or (a.value, a.unit) != (b.value, b.unit)):
                reasons.append(f"tolerance {name}: {f'{a.value:g} {a.unit}' if a else 'new'} -> {b.value:g} {b.unit}")
        if old_def.check != new_def.check:
            reasons.append(f"scoring rule {old_def.check} -> {new_def.check}")
    if new_item is not None:
        reasons.append(new_item.feedback)
    return "; ".join(reasons)


def _override_notes(report: dict, overrides) -> list[str]:
    """Per override, what the regrade does with it: kept beside the new version's measured verdict and score, capped
    at the item's new points, or dropped with an item the new version no longer has."""
    items = {i["id"]: i for i in report["items"]}
    notes = []
    for o in overrides:
        item = items.get(o.item_id)
        if item is None:
            notes.append(f"{o.item_id}: override {o.score:g} by {o.by.name} dropped: the new version has no such item")
            continue
        measured = f"the new version measures {item['verdict'].replace('_', ' ')}, {item['score']:g}"
        if o.score > item["points"]:
            notes.append(f"{o.item_id}: override {o.score:g} by {o.by.name} kept, capped at the item's new "
                         f"{item['points']:g} points ({measured})")
        else:
            notes.append(f"{o.item_id}: override {o.score:g} of {item['points']:g} by {o.by.name} kept ({measured})")
    return notes


def _regrade_one(submission: Submission, grade: Grade, old_rubric, new_rubric, overrides=()):
    """(entry, new report as stored (a dict, overrides applied) or None) for one submission, from its stored
    measurements only."""

    entry = dict(submission_id=submission.id, student=submission.student.name, old_version=grade.rubric_version,
                 new_version=new_rubric.version, old_total=grade.total, new_total=None, max_total=None,
                 changed_items=[])
    if (grade.rubric_version, grade.rubric_hash) == (new_rubric.version, new_rubric.content_hash):
        return RegradeEntry(**entry, skipped=f"already graded under v{new_rubric.version}"), None
    if grade.completed_at is None:  # its lab check is being added to the stored grade (worker.grading.complete_grade)
        return RegradeEntry(**entry, skipped="its lab check is still being evaluated: regrade it once it is "
                                             "(seconds)"), None
    try:
        sheet = rubric.parse_sheet(submission.sheet, submission.part)
        measured = {run.name for run in submission.case_runs}
        variant = submission_variant(submission)  # a variant submission is regraded under its own variant
        missing = sorted(spec.name for spec in rubric.cases_to_run(sheet, new_rubric, variant)
                         if spec.name not in measured)
        if missing:
            return RegradeEntry(**entry, skipped=f"v{new_rubric.version} needs cases never measured for this "
                                                 f"submission: {', '.join(missing)}"), None
        new = grading.score(submission, new_rubric)
        results = {run.name: stored_result(run) for run in submission.case_runs}
        reused = {run.name: run.reused_from_id for run in submission.case_runs if run.reused_from_id}
        check, _ = lab_check(results, rubric=new_rubric, reused=reused, artifacts_dir=settings.artifacts_dir,
                             variant=variant)
        new = new.model_copy(update={"check": check})
    except Exception as exc:  # one submission that cannot be regraded must not hide the others
        return RegradeEntry(**entry, skipped=f"regrading failed: {type(exc).__name__}: {exc}"), None
    measured = new.model_dump(mode="json")
    stored = overridden_report(measured, overrides) if overrides else measured
    old = rubric.GradeReport.model_validate(grade.report)
    row = report_changes({"s": old}, {"s": rubric.GradeReport.model_validate(stored)}).rows[0]
    new_items = {i.id: i for i in new.items}
    entry.update(new_total=stored["total"], max_total=stored["max_total"], changed_items=[
        ItemDiff(**change.model_dump(), why=_why(change.id, old_rubric, new_rubric, new_items.get(change.id)))
        for change in row.changed_items], overrides=_override_notes(measured, overrides))
    return RegradeEntry(**entry), stored


def _check(**fields: str) -> None:
    """Invalid naming each field (lesson, version, content_hash) that cannot name a rubric version: a page's form
    sends any text, and such a value must be a clear 422, not a failed lookup."""
    errors = [{"field": name, "rule": f"must match {RULES[name]}, at most {MAX_LENGTH[name]} characters"}
              for name, value in fields.items()
              if len(value) > MAX_LENGTH[name] or not re.fullmatch(RULES[name], value)]
    if errors:
        raise Invalid("invalid regrade request", errors)


def _old_rubric(session: Session, course: Course, grade: Grade):
    """The rubric a grade was scored under, by its content hash; a grade stored with no such row reads the course's."""
    return (stored_version(session, grade.rubric_lesson, grade.rubric_version, grade.rubric_hash)
            or get_version(session, grade.rubric_lesson, grade.rubric_version, course_id=course.id))


def _compute(session: Session, course: Course, lesson: str, version: str):
    started = time.perf_counter()
    try:
        new_rubric = get_version(session, lesson, version, course_id=course.id)
        current = course_version(session, course.id, lesson)
        graded = _graded(session, course, lesson)
        old_rubrics = {g.rubric_hash: _old_rubric(session, course, g) for _, g in graded}
    except LookupError as exc:  # another course's version is unknown here too, and never named
        raise NotFound(str(exc)) from exc
    try:
        ensure_gradable(new_rubric)
    except ArchivedRubric as exc:
        raise Conflict(str(exc)) from exc
    results = [_regrade_one(s, g, old_rubrics[g.rubric_hash], new_rubric, current_overrides(session, s.id))
               for s, g in graded]
    preview = RegradePreview(
        course=course.name, lesson=lesson, current_version=current, new_version=new_rubric.version,
        content_hash=new_rubric.content_hash,
        rubric_changes={r.version: rubric_changes(r, new_rubric) for r in old_rubrics.values()
                        if r.content_hash != new_rubric.content_hash},
        entries=[entry for entry, _ in results], elapsed_s=time.perf_counter() - started)
    return preview, results, new_rubric


def preview_regrade(session: Session, *, course: Course, lesson: str, version: str) -> RegradePreview:
    """What regrading every current grade of the course's lesson under `version` would change; writes nothing.

    NotFound for a version the course may not read, Conflict for one that can no longer grade."""
    _check(lesson=lesson, version=version)
    preview, _, _ = _compute(session, course, lesson, version)
    session.rollback()  # recording shipped versions is the only write a preview may cause; keep none
    return preview


def commit_regrade(session: Session, *, course: Course, lesson: str, version: str, content_hash: str,
                   user: User) -> tuple[Regrade, RegradePreview]:
    """Regrade under `version` and write it (commits): new current grades, the old ones superseded and kept.
    `content_hash`: the content its preview showed; Conflict if the version the course reads now has other content."""
    _check(lesson=lesson, version=version, content_hash=content_hash)
    preview, results, new_rubric = _compute(session, course, lesson, version)
    if new_rubric.content_hash != content_hash:
        session.rollback()
        rule = (f"previewed {content_hash[:12]}, but {lesson} v{version} now has content "
                f"{new_rubric.content_hash[:12]}; preview again")
        raise Conflict(f"content_hash: {rule}", [{"field": "content_hash", "rule": rule}])
    now = utcnow()
    regrade = Regrade(course_id=course.id, lesson=lesson, version=new_rubric.version, committed_by_id=user.id,
                      committed_at=now, regraded=0, changed=len(preview.changed),
                      skipped=[{"submission_id": e.submission_id, "student": e.student, "reason": e.skipped}
                               for e in preview.entries if e.skipped])
    session.add(regrade)
    session.flush()
    submissions = {s.id: s for s, _ in _graded(session, course, lesson)}
    for entry, report in results:
        if report is None:
            continue
        # its lab check was evaluated again on the runs already stored: the new grade is complete
        stored = grading.store_grade(session=session, submission=submissions[entry.submission_id], book=new_rubric,
                                     report=rubric.GradeReport.model_validate(report),
                                     execution_s=preview.elapsed_s / max(len(results), 1), complete=True,
                                     regrade=regrade, now=now)
        # the overrides it keeps (the rubric's report model has no field for them): stored as the preview showed
        stored.report, stored.total, stored.max_total = report, report["total"], report["max_total"]
        regrade.regraded += 1
    try:
        session.commit()
    except IntegrityError as exc:  # the one-current-grade index: another commit got there first
        session.rollback()
        raise Conflict("another regrade of this course committed at the same time; preview again") from exc
    return regrade, preview


def regrade_records(session: Session, *, course: Course, lesson: str | None = None) -> list[RegradeRecord]:
    """The course's committed regrades (of one lesson, or all), newest first, with who committed each and when."""
    query = select(Regrade).where(Regrade.course_id == course.id)
    if lesson is not None:
        query = query.where(Regrade.lesson == lesson)
    return [record(r, course) for r in session.scalars(query.order_by(Regrade.id.desc()))]


def rubric_versions(session: Session, *, course: Course, lesson: str) -> list[RubricVersion]:
    """The rubric versions of the lesson the course may read, oldest first: the shipped ones, recorded on first sight
    (commits), and the course's own published ones; another course's are never listed."""
    rows = course_versions(session, course.id, lesson)
    session.commit()
    return rows
