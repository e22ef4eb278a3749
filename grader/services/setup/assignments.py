"""Assignments: which rubric items one holds, the dates that apply to a student, whether a submission may be taken
now, how a late attempt's penalty turns its raw score into the counted one, and which items a student sees yet; and
the instructor's changes to them (create, update, release, extensions), each recorded with who made it
(grader.services.setup.course_changes)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from datetime import UTC, datetime, timedelta
from functools import cache

from pydantic import BaseModel, ValidationError
from sqlalchemy import func, select
from sqlalchemy.orm import Session, defer

from grader.core.lti_outbox import scores_changed
from grader.core.grades import current_grade
from grader.core.states import AssignmentParts, CountedAttempt, Role, Visibility
from grader.core.timezones import iso, local
from grader.core.models import Assignment, Course, Extension, Grade, Submission, User, utcnow
from grader.core.schemas import AssignmentCreate, CountedGradePublic, ExtensionCreate
from grader.services.setup import course_changes
from grader.services.identity.access import MAX_ID, require_course_instructor
from grader.services.setup.course_changes import ChangeKind
from grader.services.errors import Conflict, Invalid, NotFound, Refused
from rubric import load_rubric

DAY_S = 86400
HOUR = timedelta(hours=1)
# Gradescope's per-test visibility for each of ours (its "after_published": once the instructor publishes grades).
GRADESCOPE_VISIBILITY = {Visibility.IMMEDIATE: "visible", Visibility.AFTER_DUE: "after_due_date",
                         Visibility.ON_RELEASE: "after_published"}


def item_ids(lesson: str, part: str) -> list[str]:
    """The rubric items an assignment holds: checkpoints (part "checkpoint"), exercises (every other part), sheet."""
    return list(_item_ids(lesson, part))


@cache  # the shipped rubric files do not change under a running process; loading one took ~3 ms of each API read
def _item_ids(lesson: str, part: str) -> tuple[str, ...]:
    rubric = load_rubric(lesson)
    if part == AssignmentParts.CHECKPOINTS:
        return tuple(i.id for i in rubric.items if i.part == "checkpoint")
    if part == AssignmentParts.EXERCISES:
        return tuple(i.id for i in rubric.items if i.part != "checkpoint")
    return tuple(i.id for i in rubric.items)


@dataclass(frozen=True)
class Dates:
    due_at: datetime
    hard_close_at: datetime
    extension: Extension | None


def dates_for(*, session: Session, assignment: Assignment, student: User) -> Dates:
    """The assignment's due date and hard close, or the student's extension when one was granted."""
    ext = extension_of(session=session, assignment=assignment, student=student)
    if ext is not None:
        return Dates(ext.due_at, ext.hard_close_at, ext)
    return Dates(assignment.due_at, assignment.hard_close_at, None)


def attempts_used(*, session: Session, assignment: Assignment, student: User) -> int:
    return session.scalar(select(func.count()).select_from(Submission).where(
        Submission.assignment_id == assignment.id, Submission.student_id == student.id))


def submitted_last_hour(*, session: Session, assignment: Assignment, student: User, now: datetime) -> list[datetime]:
    return list(session.scalars(select(Submission.created_at).where(
        Submission.assignment_id == assignment.id, Submission.student_id == student.id,
        Submission.created_at > now - HOUR).order_by(Submission.created_at)))


def admit(*, session: Session, assignment: Assignment, student: User, now: datetime) -> tuple[int, int]:
    """(attempt number, seconds late) for a submission at `now` (naive UTC); Refused before open, after the hard
    close that applies to the student, beyond the attempt limit or beyond the submissions allowed per hour."""
    tz = assignment.course.timezone
    # The API's English rule, and the same as facts for a page to say in its reader's words (grader.pages.errors).
    facts = {"assignment": assignment.title, "assignment_id": assignment.id, "now": now}
    if now < assignment.open_at:
        raise Refused("assignment_id", f"assignment {assignment.id} opens at {iso(assignment.open_at, tz)}; "
                                       f"it is {iso(now, tz)}", reason="opens", facts=facts | {"at": assignment.open_at})
    dates = dates_for(session=session, assignment=assignment, student=student)
    if now > dates.hard_close_at:
        whose = "your extension's" if dates.extension else "its"
        raise Refused("assignment_id", f"assignment {assignment.id} closed at {iso(dates.hard_close_at, tz)} "
                                       f"({whose} hard close); it is {iso(now, tz)}",
                      reason="closed_extension" if dates.extension else "closed",
                      facts=facts | {"at": dates.hard_close_at})
    used = attempts_used(session=session, assignment=assignment, student=student)
    if assignment.max_attempts is not None and used >= assignment.max_attempts:
        raise Refused("assignment_id", f"assignment {assignment.id} allows {assignment.max_attempts} attempt{'' if assignment.max_attempts == 1 else 's'}; "
                                       f"{used} already submitted", reason="attempts",
                      facts=facts | {"allowed": assignment.max_attempts, "used": used})
    if assignment.max_per_hour is not None:
        recent = submitted_last_hour(session=session, assignment=assignment, student=student, now=now)
        if len(recent) >= assignment.max_per_hour:
            # The window frees a place when the oldest submission that fills it turns an hour old.
            next_at = recent[len(recent) - assignment.max_per_hour] + HOUR
            next_at = next_at.replace(microsecond=0) + timedelta(seconds=1 if next_at.microsecond else 0)
            raise Refused("assignment_id", (
                f"assignment {assignment.id} allows {assignment.max_per_hour} submission{'' if assignment.max_per_hour == 1 else 's'} per hour; "
                f"{len(recent)} in the last hour, the next is allowed at {iso(next_at, tz)}"),
                retry_after_s=max(1, math.ceil((next_at - now).total_seconds())), reason="per_hour",
                facts=facts | {"allowed": assignment.max_per_hour, "used": len(recent), "at": next_at})
    late = max(0, math.ceil((now - dates.due_at).total_seconds()))
    return used + 1, late


def late_text(seconds: int | None) -> str:
    """'on time', or how late in days, hours and minutes and how many days the penalty charges."""
    if not seconds:
        return "on time"
    days, rest = divmod(seconds, DAY_S)
    hours, minutes = rest // 3600, rest % 3600 // 60
    parts = [f"{days} d" if days else "", f"{hours} h" if hours else "", f"{minutes} min" if minutes else "",
             f"{seconds} s" if seconds < 60 else ""]
    charged = math.ceil(seconds / DAY_S)
    return f"{' '.join(p for p in parts if p)} late ({charged} day{'s' if charged != 1 else ''} charged)"


def penalty_fraction(assignment: Assignment, late_seconds: int) -> float:
    """Per day late, any part of a day counting as a day, capped by the assignment's cap (and by 1)."""
    if late_seconds <= 0:
        return 0.0
    fraction = math.ceil(late_seconds / DAY_S) * assignment.late_penalty_per_day
    cap = 1.0 if assignment.late_penalty_cap is None else assignment.late_penalty_cap
    return min(fraction, cap, 1.0)


@dataclass(frozen=True)
class Counted:
    submission: Submission
    raw: float
    max_total: float
    penalty: float  # the fraction taken
    counted: float


def counted_score(assignment: Assignment, submission: Submission, raw: float, max_total: float) -> Counted:
    penalty = penalty_fraction(assignment, submission.late_seconds or 0)
    return Counted(submission, raw, max_total, penalty, round(raw * (1.0 - penalty), 6))


def _graded(*, session: Session, assignment: Assignment, student_id: int | None = None):
    query = (select(Submission, Grade).join(Grade, Grade.submission_id == Submission.id)
             .where(Submission.assignment_id == assignment.id, Grade.superseded_at.is_(None))
             .options(defer(Grade.report), defer(Submission.sheet)))  # totals only: never decode the big JSON
    if student_id is not None:
        query = query.where(Submission.student_id == student_id)
    return session.execute(query.order_by(Submission.attempt)).all()


def _counting(assignment: Assignment, rows) -> dict[int, Counted]:
    """Per student id, the attempt that counts: the latest graded, or the best counted score (ties to the later)."""
    by_student: dict[int, Counted] = {}
    for submission, grade in rows:
        this = counted_score(assignment, submission, grade.total, grade.max_total)
        held = by_student.get(submission.student_id)
        if held is None or assignment.counted_attempt == CountedAttempt.LATEST or this.counted >= held.counted:
            by_student[submission.student_id] = this
    return by_student


def counted_grades(*, session: Session, assignment: Assignment) -> list[Counted]:
    """Per student, the attempt that counts (latest graded, or best counted score, ties to the later), by name."""
    return sorted(_counting(assignment, _graded(session=session, assignment=assignment)).values(),
                  key=lambda c: c.submission.student.name)


def counted_public(c: Counted):
    """A counted grade as the API shows it (grader.core.schemas.CountedGradePublic)."""

    return CountedGradePublic(student=c.submission.student.name, submission_id=c.submission.id,
                              attempt=c.submission.attempt, submitted_at=c.submission.created_at,
                              late_seconds=c.submission.late_seconds or 0, raw_score=c.raw, max_score=c.max_total,
                              penalty=c.penalty, counted_score=c.counted,
                              variant=c.submission.variant.name if c.submission.variant is not None else None)


def counted_for(*, session: Session, submission: Submission) -> tuple[Counted | None, int | None]:
    """This graded submission's raw, penalty and counted score, and the id of its student's attempt that counts."""
    assignment = submission.assignment
    rows = _graded(session=session, assignment=assignment, student_id=submission.student_id)
    counting = _counting(assignment, rows).get(submission.student_id)
    mine = next((counted_score(assignment, s, g.total, g.max_total) for s, g in rows if s.id == submission.id), None)
    return mine, counting.submission.id if counting else None


def attempts_by_student(*, session: Session, assignment: Assignment) -> dict[int, list[Submission]]:
    """Every submission to the assignment, per student id, in attempt order."""
    out: dict[int, list[Submission]] = {}
    for s in session.scalars(select(Submission).where(Submission.assignment_id == assignment.id)
                             .order_by(Submission.attempt)):
        out.setdefault(s.student_id, []).append(s)
    return out


def assignment_of(*, session: Session, user: User, assignment_id: int) -> Assignment:
    """An assignment of the caller's course; NotFound for any other."""
    row = session.get(Assignment, assignment_id) if 0 < assignment_id <= MAX_ID else None
    if row is None or row.course_id != user.course_id:
        raise NotFound(f"assignment {assignment_id} not found")
    return row


def of_course(*, session: Session, course: Course) -> list[Assignment]:
    """The course's assignments, by due date."""
    return list(session.scalars(select(Assignment).where(Assignment.course_id == course.id)
                                .order_by(Assignment.due_at, Assignment.id)))


@cache
def always_shown(lesson: str) -> frozenset[str]:
    """The lesson's config items (decided from the student's own configs by the one-factor rule): shown at once
    whatever an assignment says, since the sheet form's Check tells their answer before anything is submitted, and
    which of the student's configs run tells it after (issue 44, hostile pass 7)."""
    return frozenset(i.id for i in load_rubric(lesson).items if i.kind == "config")


def _strangers(lesson: str, part: str, item_visibility: dict | None) -> list[dict[str, str]]:
    """Each per-item visibility that names no item of the assignment, or withholds a config item, as a field error."""
    held = item_ids(lesson, part)
    errors = [{"field": f"item_visibility.{item}", "rule": f"not an item of this assignment ({part}: {', '.join(held)})"}
              for item in item_visibility or {} if item not in held]
    return errors + [
        {"field": f"item_visibility.{item}",
         "rule": "a config item is always shown: the sheet form's Check tells its answer before submitting"}
        for item, seen in (item_visibility or {}).items() if item in always_shown(lesson) and seen != "immediate"]


def _validated(model: type[BaseModel], raw: dict, detail: str) -> dict:
    """`raw` checked by the API's body model: Invalid naming each field (dotted from the top) with pydantic's
    message, as grader.web.errors answers a body."""
    try:
        return model.model_validate(raw).model_dump()
    except ValidationError as exc:
        raise Invalid(detail, [{"field": ".".join(str(p) for p in e["loc"]), "rule": e["msg"]}
                               for e in exc.errors()]) from None


def checked(raw: dict) -> dict:
    """An assignment's fields checked as the API checks a body (grader.core.schemas.AssignmentCreate: the same rules, the
    same messages, each naming its field) and by create's own rule on per-item visibility: every error at once, as
    Invalid. For callers that do not come through the API's body validation (the set-up pages)."""
    try:
        fields = _validated(AssignmentCreate, raw, "invalid assignment")
    except Invalid as exc:
        if not {e["field"].partition(".")[0] for e in exc.errors} & {"lesson", "part", "item_visibility"}:
            exc.errors += _strangers(raw.get("lesson", "L03"), raw.get("part", AssignmentParts.SHEET),
                                     raw.get("item_visibility"))
        raise
    if strangers := _strangers(fields["lesson"], fields["part"], fields["item_visibility"]):
        raise Invalid("invalid assignment", strangers)
    return fields


def checked_extension(raw: dict) -> dict:
    """An extension's student and dates checked as the API checks its body (grader.core.schemas.ExtensionCreate)."""
    return _validated(ExtensionCreate, raw, "invalid extension")


def create(*, session: Session, course: Course, user: User, fields: dict) -> Assignment:
    """Store a new assignment of the course (fields validated by grader.core.schemas.AssignmentCreate); Invalid naming
    each per-item visibility that names no item of the assignment. Recorded with who created it. NotFound outside
    the course, Forbidden for anyone but its instructors (checked here, whichever door called). Commits."""
    require_course_instructor(user, course.id, action="create an assignment", thing=f"course {course.name!r}")
    if strangers := _strangers(fields["lesson"], fields["part"], fields.get("item_visibility")):
        raise Invalid("invalid assignment", strangers)
    assignment = Assignment(course_id=course.id, created_by_id=user.id, **fields)
    session.add(assignment)
    session.flush()
    course_changes.record(session=session, course=course, by=user, kind=ChangeKind.ASSIGNMENT_CREATED,
                          assignment=assignment, summary=f"created assignment {assignment.id} {assignment.title!r}",
                          detail={k: _plain(v) for k, v in fields.items()})
    session.commit()
    return assignment


def submission_count(*, session: Session, assignment: Assignment) -> int:
    return session.scalar(select(func.count()).select_from(Submission).where(
        Submission.assignment_id == assignment.id))


def update(*, session: Session, assignment: Assignment, by: User, fields: dict) -> Assignment:
    """Change an assignment's settings to `fields` (every field create takes, validated as for create): all or
    nothing, recorded with the values before and after. Once students have submitted, its lesson and part are
    fixed (Conflict naming the field): each submission's sheet answers exactly the items they select. Every other
    setting may change: late policy, counted attempt and visibility apply to the attempts already graded too, while
    each attempt keeps the lateness it was admitted with. NotFound outside the course, Forbidden for anyone but its
    instructors. Commits (nothing when nothing changed)."""
    require_course_instructor(by, assignment.course_id, action="edit an assignment",
                              thing=f"assignment {assignment.id}")
    if strangers := _strangers(fields["lesson"], fields["part"], fields.get("item_visibility")):
        raise Invalid("invalid assignment", strangers)
    changed = {k: [getattr(assignment, k), v] for k, v in fields.items() if getattr(assignment, k) != v}
    fixed = [k for k in ("lesson", "part") if k in changed]
    if fixed and (used := submission_count(session=session, assignment=assignment)):
        raise Conflict("assignment has submissions", [{"field": k, "rule": (
            f"fixed once students have submitted: {used} submission{'s' if used != 1 else ''} answer the items of "
            f"{k} {getattr(assignment, k)!r}")} for k in fixed])
    if not changed:
        return assignment
    for key, (_, new) in changed.items():
        setattr(assignment, key, new)
    tz = assignment.course.timezone
    summary = f"edited assignment {assignment.id} {assignment.title!r}: " + "; ".join(
        f"{LABELS[k]} {_shown(old, tz)} → {_shown(new, tz)}" for k, (old, new) in changed.items())
    course_changes.record(session=session, course=assignment.course, by=by, kind=ChangeKind.ASSIGNMENT_EDITED,
                          assignment=assignment, summary=summary,
                          detail={k: [_plain(old), _plain(new)] for k, (old, new) in changed.items()})
    scores_changed(session=session, assignment=assignment)  # a late policy or visibility changes counted scores
    session.commit()
    return assignment


# How a change record names each setting (grader.cli.assignment's options, in words).
LABELS = {"title": "title", "lesson": "lesson", "part": "part", "open_at": "opens", "due_at": "due",
          "hard_close_at": "hard close", "late_penalty_per_day": "late penalty per day",
          "late_penalty_cap": "late penalty cap", "max_attempts": "attempts", "max_per_hour": "submissions per hour",
          "counted_attempt": "counted attempt", "visibility": "scores shown", "item_visibility": "items shown"}


def _shown(value, tz: str) -> str:
    if value is None:
        return "none"
    if isinstance(value, datetime):
        return local(value, tz)
    if isinstance(value, dict):
        return ", ".join(f"{k} {v}" for k, v in value.items()) or "none"
    return f"{value:g}" if isinstance(value, float) else str(value)


def _plain(value):
    """A value as the change record's JSON keeps it: times as ISO 8601 UTC."""
    return value.replace(tzinfo=UTC).isoformat() if isinstance(value, datetime) else value


def release(*, session: Session, assignment: Assignment, by: User) -> Assignment:
    """Show the assignment's withheld (on_release) scores and feedback to its students; nothing is regraded. Releasing
    again keeps the first release time (and records nothing). NotFound outside the course, Forbidden for anyone but
    its instructors. Commits."""
    require_course_instructor(by, assignment.course_id, action="release an assignment",
                              thing=f"assignment {assignment.id}")
    if assignment.released_at is None:
        assignment.released_at = utcnow()
        scores_changed(session=session, assignment=assignment)  # the withheld scores may now go to the LMS
        course_changes.record(session=session, course=assignment.course, by=by, kind=ChangeKind.RELEASED,
                              assignment=assignment,
                              summary=f"released assignment {assignment.id} {assignment.title!r}: withheld "
                                      "scores and feedback shown to its students")
        session.commit()
    return assignment


def _student(*, session: Session, assignment: Assignment, student_name: str) -> User:
    student = session.scalar(select(User).where(User.course_id == assignment.course_id, User.name == student_name,
                                                User.role == Role.STUDENT))
    if student is None:
        raise Invalid("unknown student", [{"field": "student", "rule": f"no student {student_name!r} in this course"}])
    return student


def extension_of(*, session: Session, assignment: Assignment, student: User) -> Extension | None:
    return session.scalar(select(Extension).where(Extension.assignment_id == assignment.id,
                                                  Extension.student_id == student.id))


def extensions(*, session: Session, assignment: Assignment) -> list[Extension]:
    """The assignment's extensions, by student name."""
    rows = session.scalars(select(Extension).where(Extension.assignment_id == assignment.id))
    return sorted(rows, key=lambda e: e.student.name)


def grant_extension(*, session: Session, assignment: Assignment, student_name: str, due_at: datetime,
                    hard_close_at: datetime, user: User) -> Extension:
    """Give one student their own due date and hard close (replaces an earlier one); Invalid for an unknown student.
    Recorded with who granted it. NotFound outside the course, Forbidden for anyone but its instructors. Commits."""
    require_course_instructor(user, assignment.course_id, action="grant an extension",
                              thing=f"assignment {assignment.id}")
    student = _student(session=session, assignment=assignment, student_name=student_name)
    ext = extension_of(session=session, assignment=assignment, student=student)
    tz = assignment.course.timezone
    replaced = f" (was due {local(ext.due_at, tz)}, closing {local(ext.hard_close_at, tz)})" if ext else ""
    if ext is None:
        ext = Extension(assignment_id=assignment.id, student_id=student.id)
        session.add(ext)
    ext.due_at, ext.hard_close_at, ext.granted_by_id = due_at, hard_close_at, user.id
    ext.granted_at = utcnow()
    course_changes.record(
        session=session, course=assignment.course, by=user, kind=ChangeKind.EXTENSION_GRANTED, assignment=assignment,
        summary=f"extension for {student.name} on assignment {assignment.id}: due {local(due_at, tz)}, closes "
                f"{local(hard_close_at, tz)}{replaced}",
        detail={"student": student.name, "due_at": _plain(due_at), "hard_close_at": _plain(hard_close_at)})
    scores_changed(session=session, assignment=assignment)  # items shown after_due follow the student's due date
    session.commit()
    return ext


def revoke_extension(*, session: Session, assignment: Assignment, student_name: str, by: User) -> None:
    """Take a student's extension away: the assignment's own dates apply to them again (their attempts keep the
    lateness they were admitted with). Invalid naming `student` when they have none. NotFound outside the course,
    Forbidden for anyone but its instructors. Recorded. Commits."""
    require_course_instructor(by, assignment.course_id, action="revoke an extension",
                              thing=f"assignment {assignment.id}")
    student = _student(session=session, assignment=assignment, student_name=student_name)
    ext = extension_of(session=session, assignment=assignment, student=student)
    if ext is None:
        raise Invalid("no extension", [{"field": "student", "rule": (
            f"{student.name!r} has no extension of assignment {assignment.id}")}])
    tz = assignment.course.timezone
    course_changes.record(
        session=session, course=assignment.course, by=by, kind=ChangeKind.EXTENSION_REVOKED, assignment=assignment,
        summary=f"extension of {student.name} on assignment {assignment.id} revoked (was due "
                f"{local(ext.due_at, tz)}, closing {local(ext.hard_close_at, tz)}, granted by {ext.granted_by.name})",
        detail={"student": student.name, "due_at": _plain(ext.due_at), "hard_close_at": _plain(ext.hard_close_at)})
    session.delete(ext)
    scores_changed(session=session, assignment=assignment)  # items shown after_due follow the student's due date
    session.commit()


# --- the instructor's view of an assignment -----------------------------------------------------------------------

@dataclass
class AttemptRow:
    submission: Submission
    late: str
    counted: Counted | None  # None until graded
    counts: bool


@dataclass
class StudentRow:
    user: User
    extension: Extension | None
    attempts: list[AttemptRow] = field(default_factory=list)

    @property
    def counting(self) -> AttemptRow | None:
        return next((a for a in self.attempts if a.counts), None)


def students_view(*, session: Session, assignment: Assignment) -> list[StudentRow]:
    """Every student of the course (and anyone else who submitted), by name, with their attempts in order."""
    counting = {c.submission.student_id: c.submission.id
                for c in counted_grades(session=session, assignment=assignment)}
    extensions = {e.student_id: e for e in session.scalars(
        select(Extension).where(Extension.assignment_id == assignment.id))}
    attempts = attempts_by_student(session=session, assignment=assignment)
    people = {u.id: u for u in session.scalars(select(User).where(User.course_id == assignment.course_id,
                                                                  User.role == Role.STUDENT))}
    people |= {subs[0].student_id: subs[0].student for subs in attempts.values()}
    rows = []
    for user in sorted(people.values(), key=lambda u: u.name):
        row = StudentRow(user=user, extension=extensions.get(user.id))
        for s in attempts.get(user.id, []):
            grade = current_grade(session, s.id)
            counted = counted_score(assignment, s, grade.total, grade.max_total) if grade else None
            row.attempts.append(AttemptRow(submission=s, late=late_text(s.late_seconds), counted=counted,
                                           counts=counting.get(user.id) == s.id))
        rows.append(row)
    return rows
