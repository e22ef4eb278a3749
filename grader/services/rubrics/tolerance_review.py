"""A rubric version's tolerance review for one course: each tolerance beside what the course measured, the
instructors' sign-offs of the version, and a new version drafted from an old one's tolerances and published.

The comparison itself is rubric.tolerance_review (pure); this module reads what it compares from storage: the
course's stored measurements (its done case runs' metrics, one value per measurement, each with the backend,
precision and mode that produced it) and the course's audit log (stored comparisons of one case measured twice).
A sign-off is a row of its own (RubricSignoff): it never changes the version's content or hash. Publishing a draft
goes through grader.core.rubrics.publish, so rubric.governance's rules hold as they do for the API.
"""

from __future__ import annotations

import datetime as dt
import math
import re

from pydantic import BaseModel, ValidationError
from sqlalchemy import select
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from grader.core import rubrics as store
from grader.core.audit import spec_key, variant
from grader.core.states import CaseRunState
from grader.core.models import Assignment, AuditEntry, CaseRun, Course, RubricSignoff, RubricVersion, Submission, User, utcnow
from grader.core.schemas import UtcDateTime
from grader.services.identity.access import require_instructor
from grader.services.errors import Conflict, Invalid, NotFound, field_errors
from grader.services.rubrics.regrade import LESSON_PATTERN
from rubric.governance import RubricGovernanceError
from rubric.rubrics import VERSION_PATTERN, Rubric
from rubric.specs import describe_errors
from rubric.tolerance_review import (JUDGED, StoredValue, ToleranceReview, comparison_differences, review_rubric,
                                     stored_values)

NOTE_MAX = 2000
RATIONALE_MIN, RATIONALE_MAX = 20, 4000


class SignoffRecord(BaseModel):
    id: int
    by: str
    at: UtcDateTime
    note: str


PENDING_NOTE = re.compile(r"\s*\(\s*instructor sign-off pending\s*\)|;\s*instructor sign-off pending\s*(?=\))",
                          re.IGNORECASE)


def review_record(reviewer: str, *, signed_off: bool) -> str:
    """The version's own review record as a page shows it: once the course has signed it off, the shipped record's
    "instructor sign-off pending" is dropped, so the page states one sign-off status (the course's own)."""
    if not signed_off:
        return reviewer
    return PENDING_NOTE.sub("", reviewer).strip() or reviewer


class VersionReview(BaseModel):
    """Everything the review page shows of one version, for one course."""

    course: str
    lesson: str
    version: str
    content_hash: str
    source: str
    published_by: str | None
    published_at: UtcDateTime  # when this service first stored the version (shipped) or it was published here
    reviewer: str  # the version's review record, without "sign-off pending" once the course signed it off
    review_date: str
    review_notes: str
    tolerances: list[ToleranceReview]
    signoffs: list[SignoffRecord]
    measurements: int  # stored measurements of the course read
    audit_entries: int  # audit comparisons of the course read

    @property
    def pending(self) -> bool:
        """No instructor of the course has signed this content off (a shipped version's record says so itself)."""
        return not self.signoffs

    @property
    def flagged(self) -> list[ToleranceReview]:
        return [t for t in self.tolerances if t.flagged]


def _version_row(session: Session, course: Course, lesson: str, version: str) -> RubricVersion:
    """The version as the course reads it; NotFound (naming only the course's own versions) otherwise."""
    if not re.fullmatch(LESSON_PATTERN, lesson) or len(version) > 32 or not re.fullmatch(VERSION_PATTERN, version):
        raise NotFound(f"rubric {lesson} version {version} not found")
    rows = store.course_versions(session, course.id, lesson)
    row = next((r for r in rows if r.version == version), None)
    if row is None:
        raise NotFound(f"lesson {lesson} has no rubric version {version!r}; known: "
                       f"{', '.join(r.version for r in rows) or 'none'}")
    return row


def _stored(session: Session, course: Course, lesson: str) -> list[StoredValue]:
    """Every judged quantity of the course's stored measurements, one value per measurement (runs that reused a
    measurement repeat its numbers and count once), each with the variant that produced it."""
    runs = session.scalars(select(CaseRun).join(Submission, CaseRun.submission_id == Submission.id).where(
        Submission.course_id == course.id, Submission.lesson == lesson, CaseRun.status == CaseRunState.DONE,
        CaseRun.result_status == "ok", CaseRun.metrics.is_not(None)).order_by(CaseRun.id))
    quantities = sorted({q for judged in JUDGED.values() for q in judged.quantities})
    seen, out = set(), []
    for run in runs:
        key = run.content_key or f"run-{run.id}"
        if key in seen or not run.metrics:  # a JSON null passes IS NOT NULL on PostgreSQL
            continue
        seen.add(key)
        for quantity in quantities:
            for lane, value in stored_values(run.metrics, quantity):
                if math.isfinite(value):
                    out.append(StoredValue(case=run.name, spec_key=run.spec_key or spec_key(run.spec),
                                           case_run_id=run.id, variant=variant(run), quantity=quantity, lane=lane,
                                           value=value))
    return out


def _differences(session: Session, course: Course, lesson: str):
    entries = [e for e in session.scalars(select(AuditEntry).where(
        AuditEntry.course_id == course.id, AuditEntry.lesson == lesson).order_by(AuditEntry.id))
        if e.comparison]  # not_compared and provenance entries hold no comparison (SQL NULL or JSON null)
    out = []
    for e in entries:
        lanes = [lane.get("name") for lane in (e.spec or {}).get("lanes") or []]
        out += comparison_differences(e.id, e.case, e.left_variant, e.right_variant, (e.spec or {}).get("kind", ""),
                                      lanes, e.comparison)
    return out, len(entries)


def signoffs(session: Session, course: Course, row: RubricVersion) -> list[SignoffRecord]:
    """The course's sign-offs of this row's content, oldest first."""
    rows = session.scalars(select(RubricSignoff).where(
        RubricSignoff.version_id == row.id, RubricSignoff.course_id == course.id,
        RubricSignoff.content_hash == row.content_hash).order_by(RubricSignoff.id))
    return [SignoffRecord(id=s.id, by=s.user.name, at=s.at, note=s.note) for s in rows]


def pending_signoffs(session: Session, *, course: Course) -> list[tuple[str, str]]:
    """(lesson, version) of each rubric version the course grades new submissions under that no instructor of the
    course has signed off yet: the dashboard's "what changed" lists them."""
    lessons = sorted({"L03", *session.scalars(select(Assignment.lesson).where(Assignment.course_id == course.id))})
    pending = []
    for lesson in lessons:
        version = store.course_version(session, course.id, lesson)
        if not signoffs(session, course, _version_row(session, course, lesson, version)):
            pending.append((lesson, version))
    return pending


def signoff_states(session: Session, *, course: Course, rows: list[RubricVersion]) -> dict[str, list[SignoffRecord]]:
    """Version -> the course's sign-offs of it (empty: pending), for the rubric list."""
    return {row.version: signoffs(session, course, row) for row in rows}


def version_review(session: Session, *, course: Course, lesson: str, version: str) -> VersionReview:
    """One version's tolerances beside the course's measurements and audit log, and its sign-offs; writes nothing
    but the shipped versions' rows on first sight (committed, as the rubric list does)."""
    row = _version_row(session, course, lesson, version)
    rubric: Rubric = store.get_version(session, lesson, version, course_id=course.id)
    stored = _stored(session, course, lesson)
    differences, entries = _differences(session, course, lesson)
    done = signoffs(session, course, row)
    review = VersionReview(
        course=course.name, lesson=lesson, version=version, content_hash=row.content_hash, source=row.source,
        published_by=row.published_by.name if row.published_by else None, published_at=row.published_at,
        reviewer=review_record(rubric.review.reviewer, signed_off=bool(done)),
        review_date=rubric.review.review_date.isoformat(),
        review_notes=rubric.review.notes, tolerances=review_rubric(rubric, stored, differences),
        signoffs=done, measurements=len({v.case_run_id for v in stored}),
        audit_entries=entries)
    session.commit()
    return review


def sign_off(session: Session, *, course: Course, user: User, lesson: str, version: str, note: str) -> RubricSignoff:
    """Record `user`'s sign-off of the version's current content for the course (commits); the version itself is
    not touched. Invalid for an over-long note, Conflict when this instructor already signed this content off."""
    require_instructor(user, action="sign a rubric version off")
    note = note.strip()
    if len(note) > NOTE_MAX:
        raise Invalid("invalid sign-off", [{"field": "note", "rule": f"at most {NOTE_MAX} characters"}])
    row = _version_row(session, course, lesson, version)
    mine = next((s for s in signoffs(session, course, row) if s.by == user.name), None)
    if mine is not None:
        raise Conflict(f"{user.name} already signed {lesson} v{version} off at {mine.at:%Y-%m-%d %H:%M} UTC")
    signoff = RubricSignoff(version_id=row.id, course_id=course.id, content_hash=row.content_hash, user_id=user.id,
                            at=utcnow(), note=note)
    session.add(signoff)
    session.commit()
    return signoff


# --- drafting a new version from an old one's tolerances --------------------------------------------------------

class DraftTolerance(BaseModel):
    name: str
    value: str  # as typed: the form sends text
    unit: str
    rationale: str
    base_value: float
    base_rationale: str
    items: list[str]


class Draft(BaseModel):
    lesson: str
    base_version: str
    version: str
    notes: str
    tolerances: list[DraftTolerance]


def _next_version(rows: list[RubricVersion]) -> str:
    newest = max((r.version for r in rows), key=lambda v: tuple(int(p) for p in v.split(".")), default="0")
    return str(int(newest.split(".")[0]) + 1)


def draft_from(session: Session, *, course: Course, lesson: str, version: str) -> Draft:
    """A draft pre-filled from the version's tolerances, named with the next free major version."""
    row = _version_row(session, course, lesson, version)
    rubric: Rubric = store.get_version(session, lesson, version, course_id=course.id)
    used = {name: [i.id for i in rubric.items if name in i.tolerances] for name in rubric.tolerances}
    draft = Draft(lesson=lesson, base_version=row.version, version=_next_version(
        store.course_versions(session, course.id, lesson)), notes="", tolerances=[
        DraftTolerance(name=name, value=repr(t.value), unit=t.unit, rationale=t.rationale, base_value=t.value,
                       base_rationale=t.rationale, items=used[name]) for name, t in rubric.tolerances.items()])
    session.commit()
    return draft


def _value(name: str, text: str, errors: list[dict]) -> float | None:
    try:
        value = float(text.strip())
    except ValueError:
        value = math.nan
    if not math.isfinite(value) or value < 0:
        errors.append({"field": f"tolerances.{name}.value", "rule": "must be a finite number >= 0"})
        return None
    return value


def _changed_tolerances(base: Rubric, values: dict[str, str], rationales: dict[str, str], user: User,
                        today: dt.date) -> tuple[dict, list[str], list[dict]]:
    """(the new tolerances as content, the names changed, errors naming item and field)."""
    errors, changed, out = [], [], {}
    unknown = sorted(set(values) - set(base.tolerances))
    errors += [{"field": f"tolerances.{name}", "rule": f"v{base.version} has no such tolerance"} for name in unknown]
    for name, tol in base.tolerances.items():
        record = tol.model_dump(mode="json")
        value = _value(name, values.get(name, f"{tol.value!r}"), errors)
        rationale = " ".join(rationales.get(name, tol.rationale).split())
        if value is None:
            continue
        if value != tol.value and rationale == " ".join(tol.rationale.split()):
            errors.append({"field": f"tolerances.{name}.rationale", "rule": (
                f"changed {tol.value:g} -> {value:g} {tol.unit} (items {', '.join(_items(base, name)) or 'none'}): "
                "a changed tolerance needs a new rationale")})
            continue
        if not RATIONALE_MIN <= len(rationale) <= RATIONALE_MAX:
            errors.append({"field": f"tolerances.{name}.rationale",
                           "rule": f"between {RATIONALE_MIN} and {RATIONALE_MAX} characters"})
            continue
        if (value, rationale) != (tol.value, " ".join(tol.rationale.split())):
            changed.append(name)
            record |= {"value": value, "rationale": rationale, "reviewer": user.name,
                       "review_date": today.isoformat()}
        out[name] = record
    return out, changed, errors


def _items(rubric: Rubric, name: str) -> list[str]:
    return [i.id for i in rubric.items if name in i.tolerances]


def publish_draft(session: Session, *, course: Course, user: User, lesson: str, base_version: str, version: str,
                  notes: str, values: dict[str, str], rationales: dict[str, str]) -> RubricVersion:
    """Publish a new version: the base version's content with the changed tolerances, each re-reviewed by `user`
    today with its new rationale, and a review record of its own (commits). Invalid naming the tolerance and field
    for a changed value without a new rationale, a bad number or version, or nothing changed; Conflict where
    rubric.governance refuses (a used or shipped version string, an unreviewed change)."""
    require_instructor(user, action="publish rubric versions")
    base = store.get_version(session, lesson, _version_row(session, course, lesson, base_version).version,
                             course_id=course.id)
    errors = []
    if len(version) > 32 or not re.fullmatch(VERSION_PATTERN, version):
        errors.append({"field": "version", "rule": f"must match {VERSION_PATTERN}, at most 32 characters"})
    notes = " ".join(notes.split())
    if not 1 <= len(notes) <= NOTE_MAX:
        errors.append({"field": "review.notes", "rule": f"say what this version changes and why (1 to {NOTE_MAX} "
                                                       "characters)"})
    today = utcnow().date()
    tolerances, changed, tol_errors = _changed_tolerances(base, values, rationales, user, today)
    errors += tol_errors
    if not errors and not changed:
        errors.append({"field": "tolerances", "rule": f"no tolerance differs from v{base.version}: nothing to publish"})
    if errors:
        raise Invalid(f"draft of {lesson} v{version} refused", errors)
    content = base.model_dump(mode="json") | {
        "version": version, "tolerances": tolerances,
        "review": {"reviewer": user.name, "review_date": today.isoformat(),
                   "notes": f"{notes} (drafted from v{base.version}; changed: {', '.join(changed)})"}}
    try:
        row = store.publish(session, content=content, user=user)
        session.commit()
    except ValidationError as exc:
        session.rollback()
        raise Invalid(f"draft of {lesson} v{version} refused", field_errors(describe_errors(exc))) from exc
    except RubricGovernanceError as exc:
        session.rollback()
        raise Conflict(str(exc), [{"field": "version", "rule": str(exc)}]) from exc
    except IntegrityError as exc:
        session.rollback()
        raise Conflict("this version was published at the same time; draft again under another version") from exc
    return row
