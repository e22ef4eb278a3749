"""Assignments: which rubric items one holds, the dates that apply to a student, whether a submission may be taken
now, and how a late attempt's penalty turns its raw score into the counted one."""

from __future__ import annotations

import math
from dataclasses import dataclass
from datetime import datetime

from sqlalchemy import func, select
from sqlalchemy.orm import Session

from grader.models import Assignment, Extension, Submission, User

DAY_S = 86400


def item_ids(lesson: str, items: str) -> list[str]:
    """The rubric items an assignment holds: checkpoints (part "checkpoint"), exercises (every other part), sheet."""
    from rubric import load_rubric

    rubric = load_rubric(lesson)
    if items == "checkpoints":
        return [i.id for i in rubric.items if i.part == "checkpoint"]
    if items == "exercises":
        return [i.id for i in rubric.items if i.part != "checkpoint"]
    return [i.id for i in rubric.items]


@dataclass(frozen=True)
class Dates:
    due_at: datetime
    hard_close_at: datetime
    extension: Extension | None


def dates_for(*, session: Session, assignment: Assignment, student: User) -> Dates:
    """The assignment's due date and hard close, or the student's extension when one was granted."""
    ext = session.scalar(select(Extension).where(Extension.assignment_id == assignment.id,
                                                 Extension.student_id == student.id))
    if ext is not None:
        return Dates(ext.due_at, ext.hard_close_at, ext)
    return Dates(assignment.due_at, assignment.hard_close_at, None)


def attempts_used(*, session: Session, assignment: Assignment, student: User) -> int:
    return session.scalar(select(func.count()).select_from(Submission).where(
        Submission.assignment_id == assignment.id, Submission.student_id == student.id))


class Refused(Exception):
    """A submission the assignment does not take now; `field` and `rule` say why (with the time that applies)."""

    def __init__(self, field: str, rule: str):
        super().__init__(rule)
        self.field, self.rule = field, rule


def iso(at: datetime) -> str:
    return at.isoformat() + "+00:00"


def admit(*, session: Session, assignment: Assignment, student: User, now: datetime) -> tuple[int, int]:
    """(attempt number, seconds late) for a submission at `now` (naive UTC); Refused before open, after the hard
    close that applies to the student, or beyond the attempt limit."""
    if now < assignment.open_at:
        raise Refused("assignment_id", f"assignment {assignment.id} opens at {iso(assignment.open_at)}; "
                                       f"it is {iso(now)}")
    dates = dates_for(session=session, assignment=assignment, student=student)
    if now > dates.hard_close_at:
        whose = "your extension's" if dates.extension else "its"
        raise Refused("assignment_id", f"assignment {assignment.id} closed at {iso(dates.hard_close_at)} ({whose} "
                                       f"hard close); it is {iso(now)}")
    used = attempts_used(session=session, assignment=assignment, student=student)
    if assignment.max_attempts is not None and used >= assignment.max_attempts:
        raise Refused("assignment_id", f"assignment {assignment.id} allows {assignment.max_attempts} attempts; "
                                       f"{used} already submitted")
    late = max(0, math.ceil((now - dates.due_at).total_seconds()))
    return used + 1, late


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


def lesson_results(*, session: Session, backend: str = "cpu") -> dict:
    """The lesson's own cases as already measured for any submission (the latest valid run of each on `backend`),
    read back from storage: what a checkpoint sheet is graded on without running anything. A case never measured
    yet is absent, and the items that need it say 'not measured'."""
    from rubric import BASELINE_CASES
    from rubric.scoring import LESSON_RUNS

    from grader.core.audit import spec_key
    from grader.core.lifecycle import stored_result
    from grader.models import CaseRun

    results = {}
    for name in LESSON_RUNS:
        spec = BASELINE_CASES[name].model_dump(mode="json", exclude_computed_fields=True)
        run = session.scalar(select(CaseRun).where(
            CaseRun.spec_key == spec_key(spec), CaseRun.backend == backend, CaseRun.precision == spec["precision"],
            CaseRun.purpose == "grading", CaseRun.status == "done", CaseRun.result_status == "ok")
            .order_by(CaseRun.id.desc()).limit(1))
        if run is not None:
            results[name] = stored_result(run)
    return results


def grade_now(*, session: Session, submission: Submission, sheet, backend: str = "cpu"):
    """Grade a submission that needs no case (a checkpoint sheet) in the request that stores it; the caller commits."""
    import time

    import rubric

    from grader.core.lifecycle import touch
    from grader.core.rubrics import course_rubric
    from grader.models import Grade, utcnow

    started = time.perf_counter()
    book = course_rubric(session, submission.course_id, submission.lesson)
    report = rubric.grade_sheet(sheet, lesson_results(session=session, backend=backend), book)
    grade = Grade(submission_id=submission.id, rubric_lesson=book.lesson, rubric_version=str(book.version),
                  rubric_hash=book.content_hash, total=report.total, max_total=report.max_total,
                  report=report.model_dump(mode="json"), execution_s=time.perf_counter() - started)
    session.add(grade)
    submission.graded_at = utcnow()
    touch(submission, "graded", f"{report.total:g} / {report.max_total:g} (no case to run)", session=session)
    return grade


def counted_grades(*, session: Session, assignment: Assignment) -> list[Counted]:
    """Per student, the attempt that counts (latest graded, or best counted score, ties to the later), by name."""
    from grader.models import Grade

    rows = session.execute(select(Submission, Grade).join(Grade, Grade.submission_id == Submission.id)
                           .where(Submission.assignment_id == assignment.id, Grade.superseded_at.is_(None))
                           .order_by(Submission.attempt)).all()
    by_student: dict[int, Counted] = {}
    for submission, grade in rows:
        this = counted_score(assignment, submission, grade.total, grade.max_total)
        held = by_student.get(submission.student_id)
        if held is None or assignment.counted_attempt == "latest" or this.counted >= held.counted:
            by_student[submission.student_id] = this
    return sorted(by_student.values(), key=lambda c: c.submission.student.name)


def withheld(*, session: Session, submission: Submission, user: User, now: datetime) -> str | None:
    """Why `user` may not see this submission's scores and feedback yet, or None. Staff always see them; a student
    sees them at once (immediate), from the due date that applies to them (after_due) or once released."""
    assignment = submission.assignment
    if assignment is None or user.role != "student" or assignment.visibility == "immediate":
        return None
    if assignment.visibility == "after_due":
        due = dates_for(session=session, assignment=assignment, student=submission.student).due_at
        return None if now >= due else f"scores and feedback are shown after the due date, {iso(due)}"
    if assignment.released_at is None:
        return f"scores and feedback are shown once assignment {assignment.id} is released by an instructor"
    return None
