"""The grade is stored as soon as the rubric has run; the lab check joins it after, once, and a grade left
incomplete by a worker that died while completing it is found by the reconciler. Real measured runs (the
session's Genesis cases), the real app in-process on SQLite, the worker's own grading functions."""

from __future__ import annotations

import shutil
from datetime import timedelta

from sqlalchemy import select

from rubric import CHECK_CASES

from tests.factories import mark_measured, reference_sheet, sheet_results


def _submission_ready_to_grade(api, measured, sheet: dict | None = None) -> int:
    """Alice's reference sheet (or `sheet`), its case runs stored as measured (the session's real results), now
    'grading'."""
    from grader.core.db import new_session
    from grader.core.models import Submission, utcnow
    from grader.core.settings import settings

    response = api.client.post("/v1/submissions", json={"sheet": sheet or reference_sheet()}, headers=api.as_("alice"))
    assert response.status_code == 202, response.text
    submission_id = response.json()["id"]
    results = sheet_results(measured)
    with new_session() as session:
        submission = session.get(Submission, submission_id)
        for run in submission.case_runs:
            result = results[run.name]
            folder = settings.artifacts_dir / "case-runs" / str(run.id)  # where a worker keeps a run's evidence
            shutil.copytree(result.out_dir, folder)
            mark_measured(run, result, artifact_dir=folder)
        submission.status, submission.grading_at = "grading", utcnow()
        session.commit()
    return submission_id


def _lease_passes(submission_id: int) -> None:
    """The grade task was sent longer than a lease ago (as if its worker died while completing the grade)."""
    from grader.core.db import new_session
    from grader.core.models import Submission, utcnow
    from grader.core.settings import settings

    with new_session() as session:
        session.get(Submission, submission_id).grading_at = utcnow() - timedelta(seconds=settings.lease_s + 1)
        session.commit()


def _states(submission_id: int) -> list[str]:
    from grader.core.db import new_session
    from grader.core.models import Event

    with new_session() as session:
        return [e.state for e in session.scalars(select(Event).where(Event.submission_id == submission_id,
                                                                     Event.case_run_id.is_(None))
                                                 .order_by(Event.id))]


def test_the_score_is_stored_first_and_the_lab_check_joins_it_once(api, measured):
    from grader.core.db import new_session
    from grader.reconcile import find_and_requeue
    from grader.core.settings import settings
    from worker.grading import complete_grade, grade_submission

    submission_id = _submission_ready_to_grade(api, measured)
    with new_session() as session:
        grade = grade_submission(session=session, submission_id=submission_id)
        assert grade is not None and grade.completed_at is None and grade.report.get("check") is None
        total = grade.total
    assert not list((settings.artifacts_dir / "submissions").rglob("*.png")), "the service draws no PNG"

    # The student reads the score at once; the API and the page say the lab check is being evaluated.
    state = api.client.get(f"/v1/submissions/{submission_id}", headers=api.as_("alice")).json()
    assert state["status"] == "graded" and state["total"] == total and state["report_complete"] is False
    page = api.client.get(f"/submissions/{submission_id}", headers=api.as_("alice")).text
    assert "is being evaluated on the same runs" in page and 'http-equiv="refresh"' in page
    assert "L03 CHECK: " not in page and "Grading in progress" not in page

    # A worker killed while completing: within the lease nothing is re-sent; after it, the grade task is, once.
    with new_session() as session:
        assert find_and_requeue(session=session).gradings == []
    _lease_passes(submission_id)
    with new_session() as session:
        assert find_and_requeue(session=session).gradings == [submission_id]
    with new_session() as session:
        assert find_and_requeue(session=session).gradings == [], "the re-send restarted the lease"

    with new_session() as session:
        complete = complete_grade(session=session, submission_id=submission_id)
        assert complete is not None and complete.completed_at is not None and complete.total == total
        check = complete.report["check"]
    with new_session() as session:  # a duplicate delivery finds it complete and changes nothing
        assert complete_grade(session=session, submission_id=submission_id) is None
        assert grade_submission(session=session, submission_id=submission_id) is None

    assert not list((settings.artifacts_dir / "submissions").rglob("*.png")), "the browser draws the charts"
    assert check["verdict_line"].startswith("L03 CHECK: ")
    outputs = next(c for c in check["conditions"] if c["id"] == "outputs")
    # The check saw the runs' arrays under ARTIFACTS_DIR, and says where the charts come from instead of files.
    expected = f"{len(CHECK_CASES)} .npz files under ARTIFACTS_DIR"
    assert outputs["passed"] and expected in outputs["evidence"], outputs
    assert "charts: drawn in the reader's browser from the arrays stored in the database" in outputs["evidence"]
    states = _states(submission_id)
    assert states.count("graded") == 1 and states.count("lab-check") == 1
    assert states.index("graded") < states.index("lab-check"), states
    # The only "completing" event is the reconciler's re-send note (grader/reconcile.py).
    assert states[-2:] == ["completing", "lab-check"] and states.count("completing") == 1, states

    state = api.client.get(f"/v1/submissions/{submission_id}", headers=api.as_("alice")).json()
    assert state["report_complete"] is True and state["total"] == total
    page = api.client.get(f"/submissions/{submission_id}", headers=api.as_("alice")).text
    assert check["verdict_line"] in page and 'http-equiv="refresh"' not in page
    _lease_passes(submission_id)
    with new_session() as session:
        assert find_and_requeue(session=session).gradings == [], "a complete grade is never re-sent"


def test_a_regrade_skips_a_grade_whose_lab_check_is_being_evaluated(api, measured):
    from grader.core.db import new_session
    from grader.core.grades import current_grade
    from grader.core.models import Submission
    from grader.services.rubrics.regrade import _regrade_one
    from rubric import load_rubric
    from worker.grading import grade_submission

    submission_id = _submission_ready_to_grade(api, measured)
    with new_session() as session:
        grade_submission(session=session, submission_id=submission_id)
        submission = session.get(Submission, submission_id)
        book = load_rubric()
        newer = book.model_copy(update={"version": f"{book.version}.1"})
        entry, report = _regrade_one(submission, current_grade(session, submission_id), book, newer)
    assert report is None and "still being evaluated" in entry.skipped
