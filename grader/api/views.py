"""Table rows -> public schemas. What a caller may see of a grade is decided by grader.services.submissions.visibility."""

from __future__ import annotations

from collections import Counter

from sqlalchemy.orm import Session

from grader.core.states import CaseRunState, values
from grader.core.models import Grade, Submission, User
from grader.core.schemas import CaseRunPublic, GradeHistoryEntry, GradePublic, Progress, SubmissionPublic
from grader.services.submissions.visibility import GradeView, attempt_standing, grade_view


def progress(submission: Submission) -> Progress:
    counts = Counter(run.status for run in submission.case_runs)
    return Progress(total=len(submission.case_runs), **{s: counts.get(s, 0) for s in values(CaseRunState)})


def submission_public(submission: Submission, session: Session, user: User) -> SubmissionPublic:
    """The submission as `user` sees it: the scores their assignment does not show them yet are left out."""
    view = grade_view(session=session, submission=submission, user=user, report=False)  # the report only if masked
    counted = attempt_standing(session, submission, user, view)
    return SubmissionPublic(
        id=submission.id, lesson=submission.lesson, student=submission.student.name, status=submission.status,
        force_rerun=submission.force_rerun, error=submission.error, progress=progress(submission),
        created_at=submission.created_at, updated_at=submission.updated_at, graded_at=submission.graded_at,
        report_complete=None if view.stored is None else view.completed_at is not None,
        total=view.total, max_total=view.max_total, pending=view.pending,
        assignment_id=submission.assignment_id, attempt=submission.attempt, late_seconds=submission.late_seconds,
        **counted,
    )


def case_runs_public(submission: Submission, session: Session, user: User) -> list[CaseRunPublic]:
    """Every case run as `user` may see it: a run whose measurements decide an item withheld from them
    (GradeView.withheld_runs) keeps its state, spec and backends but not its provenance or metrics, nor what would
    match it to another run (its content key, measurement, reused run, wall time and start and end) or tell what it
    measured (its
    error: a run that failed says where its values went wrong)."""
    withheld = grade_view(session=session, submission=submission, user=user, report=False).withheld_runs
    runs = [CaseRunPublic.model_validate(r) for r in submission.case_runs]
    hidden = {"provenance": None, "metrics": None, "content_key": None, "measurement_id": None,
              "reused_from_id": None, "wall_s": None, "error": None, "started_at": None, "finished_at": None,
              "tries": None}
    return [r.model_copy(update=hidden) if r.name in withheld else r for r in runs]


def grade_public(view: GradeView) -> GradePublic:
    """The current grade as the caller may see it (every score and item of a withheld one masked)."""
    grade, report = view.stored, view.report
    return GradePublic(
        submission_id=grade.submission_id, total=view.total, max_total=view.max_total,
        rubric_lesson=grade.rubric_lesson, rubric_version=grade.rubric_version, rubric_hash=grade.rubric_hash,
        items=report.get("items", []), created_at=grade.created_at, superseded_at=grade.superseded_at,
        regrade_id=grade.regrade_id, pending=view.pending,
        withheld_measurements=report.get("withheld_measurements", {}),  # only a masked report has any
        check=report.get("check"),  # a masked report has none (visibility.shown_report)
    )


def grade_history_public(grades: list[Grade]) -> list[GradeHistoryEntry]:
    return [GradeHistoryEntry(rubric_version=g.rubric_version, rubric_hash=g.rubric_hash, total=g.total,
                              max_total=g.max_total, created_at=g.created_at, superseded_at=g.superseded_at,
                              regrade_id=g.regrade_id, regraded_by=g.regrade.committed_by.name if g.regrade else None,
                              current=g.superseded_at is None)
            for g in grades]
