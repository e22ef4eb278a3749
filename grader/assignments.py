"""Assignments: which rubric items one holds, the dates that apply to a student, whether a submission may be taken
now, how a late attempt's penalty turns its raw score into the counted one, and which items a student sees yet."""

from __future__ import annotations

import math
from dataclasses import dataclass
from datetime import datetime, timedelta
from functools import cache

from sqlalchemy import func, select
from sqlalchemy.orm import Session, defer

from grader.models import Assignment, Extension, Submission, User
from grader.timezones import iso

DAY_S = 86400
HOUR = timedelta(hours=1)
# Gradescope's per-test visibility for each of ours (its "after_published": once the instructor publishes grades).
GRADESCOPE_VISIBILITY = {"immediate": "visible", "after_due": "after_due_date", "on_release": "after_published"}


def item_ids(lesson: str, items: str) -> list[str]:
    """The rubric items an assignment holds: checkpoints (part "checkpoint"), exercises (every other part), sheet."""
    return list(_item_ids(lesson, items))


@cache  # the shipped rubric files do not change under a running process; loading one took ~3 ms of each API read
def _item_ids(lesson: str, items: str) -> tuple[str, ...]:
    from rubric import load_rubric

    rubric = load_rubric(lesson)
    if items == "checkpoints":
        return tuple(i.id for i in rubric.items if i.part == "checkpoint")
    if items == "exercises":
        return tuple(i.id for i in rubric.items if i.part != "checkpoint")
    return tuple(i.id for i in rubric.items)


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
    """A submission the assignment does not take now; `field` and `rule` say why (with the time that applies).
    `retry_after_s` is set when waiting helps (the hourly limit): the API answers 429 with Retry-After."""

    def __init__(self, field: str, rule: str, retry_after_s: int | None = None):
        super().__init__(rule)
        self.field, self.rule, self.retry_after_s = field, rule, retry_after_s


def submitted_last_hour(*, session: Session, assignment: Assignment, student: User, now: datetime) -> list[datetime]:
    return list(session.scalars(select(Submission.created_at).where(
        Submission.assignment_id == assignment.id, Submission.student_id == student.id,
        Submission.created_at > now - HOUR).order_by(Submission.created_at)))


def admit(*, session: Session, assignment: Assignment, student: User, now: datetime) -> tuple[int, int]:
    """(attempt number, seconds late) for a submission at `now` (naive UTC); Refused before open, after the hard
    close that applies to the student, beyond the attempt limit or beyond the submissions allowed per hour."""
    tz = assignment.course.timezone
    if now < assignment.open_at:
        raise Refused("assignment_id", f"assignment {assignment.id} opens at {iso(assignment.open_at, tz)}; "
                                       f"it is {iso(now, tz)}")
    dates = dates_for(session=session, assignment=assignment, student=student)
    if now > dates.hard_close_at:
        whose = "your extension's" if dates.extension else "its"
        raise Refused("assignment_id", f"assignment {assignment.id} closed at {iso(dates.hard_close_at, tz)} "
                                       f"({whose} hard close); it is {iso(now, tz)}")
    used = attempts_used(session=session, assignment=assignment, student=student)
    if assignment.max_attempts is not None and used >= assignment.max_attempts:
        raise Refused("assignment_id", f"assignment {assignment.id} allows {assignment.max_attempts} attempts; "
                                       f"{used} already submitted")
    if assignment.max_per_hour is not None:
        recent = submitted_last_hour(session=session, assignment=assignment, student=student, now=now)
        if len(recent) >= assignment.max_per_hour:
            # The window frees a place when the oldest submission that fills it turns an hour old.
            next_at = recent[len(recent) - assignment.max_per_hour] + HOUR
            next_at = next_at.replace(microsecond=0) + timedelta(seconds=1 if next_at.microsecond else 0)
            raise Refused("assignment_id", (
                f"assignment {assignment.id} allows {assignment.max_per_hour} submissions per hour; "
                f"{len(recent)} in the last hour, the next is allowed at {iso(next_at, tz)}"),
                retry_after_s=max(1, math.ceil((next_at - now).total_seconds())))
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


def grade_now(*, session: Session, submission: Submission, sheet):
    """Grade a checkpoint sheet in the request that stores it: every case it needs (the lesson's own) was finished on
    a stored measurement when submitted (grader.core.lifecycle.reuse_at_admission), so nothing is run or queued and
    its report lists the runs that decided the grade. The caller commits."""
    import time

    import rubric

    from grader.core.lifecycle import stored_result, touch
    from grader.core.rubrics import course_rubric
    from grader.models import Grade, utcnow

    started = time.perf_counter()
    book = course_rubric(session, submission.course_id, submission.lesson)
    report = rubric.grade_sheet(sheet, {run.name: stored_result(run) for run in submission.case_runs}, book)
    grade = Grade(submission_id=submission.id, rubric_lesson=book.lesson, rubric_version=str(book.version),
                  rubric_hash=book.content_hash, total=report.total, max_total=report.max_total,
                  report=report.model_dump(mode="json"), execution_s=time.perf_counter() - started,
                  completed_at=utcnow())  # a checkpoint set has no figures or lab check to draw
    session.add(grade)
    submission.graded_at = utcnow()
    touch(submission, "graded", f"{report.total:g} / {report.max_total:g} (no case run: graded at once on the "
                                f"lesson's cases as already measured)", session=session)
    return grade


def _graded(*, session: Session, assignment: Assignment, student_id: int | None = None):
    from grader.models import Grade

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
        if held is None or assignment.counted_attempt == "latest" or this.counted >= held.counted:
            by_student[submission.student_id] = this
    return by_student


def counted_grades(*, session: Session, assignment: Assignment) -> list[Counted]:
    """Per student, the attempt that counts (latest graded, or best counted score, ties to the later), by name."""
    return sorted(_counting(assignment, _graded(session=session, assignment=assignment)).values(),
                  key=lambda c: c.submission.student.name)


def counted_public(c: Counted):
    """A counted grade as the API shows it (grader.schemas.CountedGradePublic)."""
    from grader.schemas import CountedGradePublic

    return CountedGradePublic(student=c.submission.student.name, submission_id=c.submission.id,
                              attempt=c.submission.attempt, submitted_at=c.submission.created_at,
                              late_seconds=c.submission.late_seconds or 0, raw_score=c.raw, max_score=c.max_total,
                              penalty=c.penalty, counted_score=c.counted)


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


def visibility_of(assignment: Assignment, item_id: str) -> str:
    """The item's own visibility where the assignment sets one, else the assignment's."""
    return (assignment.item_visibility or {}).get(item_id, assignment.visibility)


def withheld_items(*, session: Session, submission: Submission, user: User, now: datetime) -> dict[str, str]:
    """{item id: why `user` may not see its score and feedback yet}. Staff see everything; a student sees an item at
    once (immediate), from the due date that applies to them (after_due) or once the assignment is released."""
    assignment = submission.assignment
    if assignment is None or user.role != "student":
        return {}
    why = {"immediate": None}
    kinds = {visibility_of(assignment, i) for i in item_ids(assignment.lesson, assignment.items)}
    if "after_due" in kinds:
        due = dates_for(session=session, assignment=assignment, student=submission.student).due_at
        why["after_due"] = None if now >= due else (
            f"shown after the due date, {iso(due, assignment.course.timezone)}")
    if "on_release" in kinds:
        why["on_release"] = None if assignment.released_at is not None else (
            f"shown once assignment {assignment.id} is released by an instructor")
    hidden = {i: why[visibility_of(assignment, i)] for i in item_ids(assignment.lesson, assignment.items)}
    return {i: reason for i, reason in hidden.items() if reason}


def withheld(*, session: Session, submission: Submission, user: User, now: datetime) -> str | None:
    """Why `user` may see none of this submission's scores and feedback yet (every item withheld), or None."""
    hidden = withheld_items(session=session, submission=submission, user=user, now=now)
    if not hidden or len(hidden) < len(item_ids(submission.assignment.lesson, submission.assignment.items)):
        return None
    return "scores and feedback are " + " and ".join(sorted(set(hidden.values())))


def shown_report(report: dict, hidden: dict[str, str]) -> dict:
    """The stored report as a student may see it: each withheld item keeps its question, points and the student's
    own prediction, but its score is None and its feedback says when it will be shown; the total counts the shown
    items only and `pending` says which points are still to come. Nothing is regraded on release."""
    if not hidden:
        return report
    items, total, shown_max, pending_points = [], 0.0, 0.0, 0.0
    for item in report.get("items", []):
        if item["id"] in hidden:
            pending_points += item["points"]  # its worth, not max_score: that would tell an inconclusive one apart
            items.append({k: item[k] for k in ("id", "part", "kind", "question", "prediction", "points")}
                         | {"score": None, "max_score": item["points"], "verdict": "pending", "expected": "",
                            "measured": "", "evidence": None, "tolerances": {}, "backends": {},
                            "feedback": f"withheld: {hidden[item['id']]}"})
        else:
            total, shown_max = total + item["score"], shown_max + item["max_score"]
            items.append(item)
    names = [i["id"] for i in items if i["id"] in hidden]
    max_total = shown_max + pending_points
    note = (f"{pending_points:g} of {max_total:g} points pending ({', '.join(names)}): "
            + "; ".join(sorted(set(hidden.values()))))
    return {**report, "items": items, "total": round(total, 6), "max_total": max_total, "pending": note}
