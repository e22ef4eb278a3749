"""A course's class dashboard, read from storage once and served both as JSON (/v1) and as the page.

Counts submissions by state, lists case runs that failed or are stuck with their reason, takes each student's
latest graded attempt for the item analysis (rubric.analysis) and the roster.
"""

from __future__ import annotations

from collections import Counter
from datetime import datetime, timedelta
from typing import Any

from pydantic import BaseModel
from sqlalchemy import select
from sqlalchemy.orm import Session

from grader.models import CaseRun, Course, Grade, Submission, utcnow
from grader.schemas import UtcDateTime
from grader.settings import settings


class RosterRow(BaseModel):
    student: str
    submission_id: int
    status: str
    submitted_at: UtcDateTime
    attempts: int
    total: float | None
    max_total: float | None


class RunProblem(BaseModel):
    case_run_id: int
    submission_id: int
    student: str
    case: str
    status: str
    reason: str
    since: UtcDateTime


class Dashboard(BaseModel):
    course: str
    lesson: str | None
    rubric_versions: list[str]
    submissions_by_state: dict[str, int]
    submissions_per_day: dict[str, int]
    problems: list[RunProblem]
    roster: list[RosterRow]
    analysis: dict[str, Any]


def _stuck(run: CaseRun, now: datetime) -> str | None:
    """Why a run that is not finished looks stuck, or None: running past its lease, queued past the queue lease."""
    if run.status == "running" and run.lease_until is not None and run.lease_until < now:
        return f"running past its lease (since {run.lease_until:%H:%M:%S} UTC) on {run.worker or 'an unknown worker'}"
    if run.status == "queued" and run.queued_at < now - timedelta(seconds=settings.queue_lease_s):
        return f"queued for more than {settings.queue_lease_s:.0f} s"
    return None


def course_dashboard(*, session: Session, course: Course) -> Dashboard:
    from rubric import class_analysis
    from rubric.scoring import GradeReport

    now = utcnow()
    submissions = session.scalars(select(Submission).where(Submission.course_id == course.id)
                                  .order_by(Submission.id)).all()
    grades = {g.submission_id: g for g in session.scalars(
        select(Grade).join(Submission, Grade.submission_id == Submission.id)
        .where(Submission.course_id == course.id, Grade.superseded_at.is_(None)))}
    latest: dict[int, Submission] = {}
    attempts: Counter[int] = Counter()
    for s in submissions:
        latest[s.student_id] = s
        attempts[s.student_id] += 1
    latest_graded: dict[int, Grade] = {}
    for s in submissions:
        if s.id in grades:
            latest_graded[s.student_id] = grades[s.id]
    problems = []
    for s in submissions:
        for run in s.case_runs:
            reason = run.error if run.status == "failed" else _stuck(run, now)
            if reason:
                problems.append(RunProblem(case_run_id=run.id, submission_id=s.id, student=s.student.name,
                                           case=run.name, status=run.status, reason=reason,
                                           since=run.finished_at or run.started_at or run.queued_at))
    reports = [GradeReport.model_validate(g.report) for g in latest_graded.values()]
    return Dashboard(
        course=course.name,
        lesson=submissions[-1].lesson if submissions else None,
        rubric_versions=sorted({g.rubric_version for g in latest_graded.values()}),
        submissions_by_state=dict(Counter(s.status for s in submissions)),
        submissions_per_day=dict(sorted(Counter(f"{s.created_at:%Y-%m-%d}" for s in submissions).items())),
        problems=problems,
        roster=[RosterRow(student=s.student.name, submission_id=s.id, status=s.status, submitted_at=s.created_at,
                          attempts=attempts[student], total=grades[s.id].total if s.id in grades else None,
                          max_total=grades[s.id].max_total if s.id in grades else None)
                for student, s in sorted(latest.items(), key=lambda kv: kv[1].student.name)],
        analysis=class_analysis(reports).model_dump(mode="json"),
    )
