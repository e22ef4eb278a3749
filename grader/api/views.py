"""Table rows -> public schemas."""

from __future__ import annotations

from collections import Counter

from sqlalchemy import select
from sqlalchemy.orm import Session

from grader.core.rubrics import current_grade
from grader import assignments
from grader.assignments import shown_report, withheld_items
from grader.models import Grade, Submission, User, utcnow
from grader.schemas import GradeHistoryEntry, GradePublic, Progress, SubmissionPublic


def progress(submission: Submission) -> Progress:
    counts = Counter(run.status for run in submission.case_runs)
    return Progress(total=len(submission.case_runs), **{s: counts.get(s, 0) for s in ("queued", "running", "done", "failed")})


def submission_public(submission: Submission, session: Session, user: User | None = None) -> SubmissionPublic:
    """`user`: the caller, whose view leaves out the scores their assignment does not show them yet."""
    grade = current_grade(session, submission.id, report=False)
    hidden = withheld_items(session=session, submission=submission, user=user, now=utcnow()) if user else {}
    shown = None
    if grade is not None:  # the report is read only when some item is withheld from this caller
        shown = shown_report(grade.report, hidden) if hidden else {"total": grade.total, "max_total": grade.max_total}
    if shown is not None and len(hidden) == len(shown.get("items", [])) > 0:
        shown = None  # every item withheld: no total at all
    counted = {}
    if submission.assignment is not None:  # the penalty follows from the lateness alone: never withheld
        counted["penalty"] = assignments.penalty_fraction(submission.assignment, submission.late_seconds or 0)
    if grade is not None and submission.assignment is not None:
        mine, counting_id = assignments.counted_for(session=session, submission=submission)
        if mine is not None and not hidden:
            counted |= {"raw_score": mine.raw, "counted_score": mine.counted}
        if not hidden or submission.assignment.counted_attempt == "latest":  # "best" would tell a hidden score
            counted["counts"] = counting_id == submission.id
    return SubmissionPublic(
        id=submission.id, lesson=submission.lesson, student=submission.student.name, status=submission.status,
        force_rerun=submission.force_rerun, error=submission.error, progress=progress(submission),
        created_at=submission.created_at, updated_at=submission.updated_at, graded_at=submission.graded_at,
        report_complete=None if grade is None else grade.completed_at is not None,
        total=shown["total"] if shown else None, max_total=shown["max_total"] if shown else None,
        pending=shown.get("pending") if shown else None,
        assignment_id=submission.assignment_id, attempt=submission.attempt, late_seconds=submission.late_seconds,
        **counted,
    )


def grade_public(grade: Grade, report: dict | None = None) -> GradePublic:
    """`report`: the grade's report as the caller may see it (grader.assignments.shown_report); the stored one if
    None."""
    shown = report is not None and "pending" in report
    report = grade.report if report is None else report
    return GradePublic(
        submission_id=grade.submission_id, total=report["total"] if shown else grade.total,
        max_total=report["max_total"] if shown else grade.max_total,
        rubric_lesson=grade.rubric_lesson, rubric_version=grade.rubric_version, rubric_hash=grade.rubric_hash,
        items=report.get("items", []), created_at=grade.created_at, superseded_at=grade.superseded_at,
        regrade_id=grade.regrade_id, pending=report.get("pending"),
    )


def grade_history_public(grades: list[Grade]) -> list[GradeHistoryEntry]:
    return [GradeHistoryEntry(rubric_version=g.rubric_version, rubric_hash=g.rubric_hash, total=g.total,
                              max_total=g.max_total, created_at=g.created_at, superseded_at=g.superseded_at,
                              regrade_id=g.regrade_id, regraded_by=g.regrade.committed_by.name if g.regrade else None,
                              current=g.superseded_at is None)
            for g in grades]
