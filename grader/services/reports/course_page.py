"""A student's course page as data: per assignment of the course, the dates that apply to them, what a submission
now would meet (admitted or refused, how late, the penalty), their attempts and the score that counts so far. Every
rule is the one the API applies (grader.services.setup.assignments), every score passes the one visibility rule
(grader.services.submissions.visibility). At an assignment with a variant pool it also states the student's own lab
(their variant's parameters, in the reader's language: rubric.variants.texts), fixed at this first view as the form
fixes it (grader.services.setup.student_variants), or that the lab is still being prepared; never another variant's."""

from __future__ import annotations

from dataclasses import dataclass, field
from datetime import datetime

from sqlalchemy import select
from sqlalchemy.orm import Session

from grader.core.models import Assignment, Submission, User, utcnow
from grader.services.setup import assignments as logic
from grader.services.setup import student_variants
from grader.services.errors import Conflict, Refused
from grader.services.submissions.visibility import attempt_standing, grade_view
from rubric.variants import texts


@dataclass(frozen=True)
class AttemptLine:
    submission: Submission
    late: str
    penalty: float
    score: float | None  # the shown total (withheld items left out), None before grading or when nothing is shown
    max_score: float | None
    counted: float | None  # after the late penalty; None while any item is withheld
    counts: bool | None  # None: withheld (under "best" it would tell a hidden score)
    withheld: str | None  # why some or all of the scores are not shown yet


@dataclass(frozen=True)
class NowLine:
    """A submission made now: admitted as attempt N, late by so much with this penalty, or refused by a rule."""

    attempt: int | None
    late_seconds: int | None
    late: str | None
    penalty: float | None
    refusal: str | None
    retry_after_s: int | None
    refused: Refused | None = None  # the refusal itself: its reason and facts, for the page to say in its words


@dataclass(frozen=True)
class LabLine:
    """The student's own lab at an assignment with a variant pool: being prepared (its variants are still measured),
    or ready with their parameters: a summary and one row per parameter (words, value, whether it differs from the
    lesson), in the reader's language."""

    ready: bool
    summary: str | None = None
    rows: list[tuple[str, str, str, bool]] = field(default_factory=list)


@dataclass(frozen=True)
class AssignmentLine:
    assignment: Assignment
    open_at: datetime
    due_at: datetime
    hard_close_at: datetime
    extension: bool
    phase: str  # upcoming | open | late | closed
    attempts_used: int
    attempts_left: int | None  # None: no limit
    last_hour: int  # submissions in the last 60 minutes (the hourly limit's window)
    now: NowLine
    attempts: list[AttemptLine] = field(default_factory=list)
    lab: LabLine | None = None  # None: no variant pool, the lesson's own parameters

    @property
    def counting(self) -> AttemptLine | None:
        return next((a for a in self.attempts if a.counts), None)

    @property
    def counting_withheld(self) -> str | None:
        """Why the attempt that counts, or its score, is not shown yet."""
        if self.counting is not None:
            return self.counting.withheld if self.counting.counted is None else None
        return next((a.withheld for a in self.attempts if a.withheld), None)


def _phase(a: Assignment, due_at: datetime, hard_close_at: datetime, now: datetime) -> str:
    if now < a.open_at:
        return "upcoming"
    if now > hard_close_at:
        return "closed"
    return "late" if now > due_at else "open"


def _now(*, session: Session, assignment: Assignment, student: User, now: datetime) -> NowLine:
    try:
        attempt, late = logic.admit(session=session, assignment=assignment, student=student, now=now)
    except Refused as refused:
        return NowLine(None, None, None, None, refused.rule, refused.retry_after_s, refused)
    return NowLine(attempt, late, logic.late_text(late), logic.penalty_fraction(assignment, late), None, None)


def _attempt(session: Session, s: Submission, student: User, now: datetime) -> AttemptLine:
    view = grade_view(session=session, submission=s, user=student, now=now, report=False)
    standing = attempt_standing(session, s, student, view)
    withheld = view.nothing_shown or view.some_withheld
    return AttemptLine(submission=s, late=logic.late_text(s.late_seconds), penalty=standing["penalty"] or 0.0,
                       score=view.total, max_score=view.max_total, counted=standing["counted_score"],
                       counts=standing["counts"], withheld=withheld if view.stored is not None else None)


def _lab(session: Session, assignment: Assignment, student: User, locale: str) -> LabLine | None:
    """The student's own lab at `assignment` (their variant, fixed now if this is their first view); None without a
    pool. A pool still measuring, or one whose every variant was dropped, is a lab being prepared."""
    try:
        variant = student_variants.student_variant(session=session, assignment=assignment, student=student)
    except Conflict:
        return LabLine(ready=False)
    if variant is None:
        return None
    return LabLine(ready=True, summary=texts.parameter_summary(variant, locale),
                   rows=texts.parameter_rows(variant, locale))


def student_course(*, session: Session, student: User, now: datetime | None = None,
                   locale: str = "en") -> list[AssignmentLine]:
    """The student's view of every assignment of their course, by due date; their lab's words in `locale`. A variant
    fixed for them here is committed (the form and a submission then meet the same one)."""
    now = now or utcnow()
    course = logic.of_course(session=session, course=student.course)
    labs = {a.id: _lab(session, a, student, locale) for a in course}
    session.commit()  # before anything else is read: what the page shows is read after it
    lines = []
    for a in course:
        dates = logic.dates_for(session=session, assignment=a, student=student)
        mine = list(session.scalars(select(Submission).where(Submission.assignment_id == a.id,
                                                             Submission.student_id == student.id)
                                    .order_by(Submission.attempt)))
        last_hour = logic.submitted_last_hour(session=session, assignment=a, student=student, now=now)
        lines.append(AssignmentLine(
            assignment=a, open_at=a.open_at, due_at=dates.due_at, hard_close_at=dates.hard_close_at,
            extension=dates.extension is not None, phase=_phase(a, dates.due_at, dates.hard_close_at, now),
            attempts_used=len(mine),
            attempts_left=None if a.max_attempts is None else max(0, a.max_attempts - len(mine)),
            last_hour=len(last_hour), now=_now(session=session, assignment=a, student=student, now=now),
            attempts=[_attempt(session, s, student, now) for s in mine], lab=labs[a.id]))
    return lines
