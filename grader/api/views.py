"""Table rows -> public schemas."""

from __future__ import annotations

from collections import Counter

from sqlalchemy import select
from sqlalchemy.orm import Session

from grader.core.rubrics import current_grade
from grader.assignments import withheld
from grader.models import Grade, Submission, User, utcnow
from grader.schemas import GradeHistoryEntry, GradePublic, Progress, SubmissionPublic


def progress(submission: Submission) -> Progress:
    counts = Counter(run.status for run in submission.case_runs)
    return Progress(total=len(submission.case_runs), **{s: counts.get(s, 0) for s in ("queued", "running", "done", "failed")})


def submission_public(submission: Submission, session: Session, user: User | None = None) -> SubmissionPublic:
    """`user`: the caller, whose view leaves out a total their assignment does not show them yet."""
    grade = current_grade(session, submission.id)
    if grade is not None and user is not None and withheld(session=session, submission=submission, user=user,
                                                           now=utcnow()):
        grade = None
    return SubmissionPublic(
        id=submission.id, lesson=submission.lesson, student=submission.student.name, status=submission.status,
        force_rerun=submission.force_rerun, error=submission.error, progress=progress(submission),
        created_at=submission.created_at, updated_at=submission.updated_at, graded_at=submission.graded_at,
        total=grade.total if grade else None, max_total=grade.max_total if grade else None,
        assignment_id=submission.assignment_id, attempt=submission.attempt, late_seconds=submission.late_seconds,
    )


def grade_public(grade: Grade) -> GradePublic:
    return GradePublic(
        submission_id=grade.submission_id, total=grade.total, max_total=grade.max_total,
        rubric_lesson=grade.rubric_lesson, rubric_version=grade.rubric_version, rubric_hash=grade.rubric_hash,
        items=grade.report.get("items", []), created_at=grade.created_at, superseded_at=grade.superseded_at,
        regrade_id=grade.regrade_id,
    )


def grade_history_public(grades: list[Grade]) -> list[GradeHistoryEntry]:
    return [GradeHistoryEntry(rubric_version=g.rubric_version, rubric_hash=g.rubric_hash, total=g.total,
                              max_total=g.max_total, created_at=g.created_at, superseded_at=g.superseded_at,
                              regrade_id=g.regrade_id, regraded_by=g.regrade.committed_by.name if g.regrade else None,
                              current=g.superseded_at is None)
            for g in grades]
