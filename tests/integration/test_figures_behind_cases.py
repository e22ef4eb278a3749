"""At a deadline the grades come first: the lab check of a stored grade (its report's completion; the charts are drawn
in the browser from the stored arrays) waits on the cpu queue behind every case run (worker.celery_app), on the real stack (Redis, PostgreSQL, one Celery worker, real Genesis cases)."""

from __future__ import annotations

import pytest
from sqlalchemy import select
from sqlalchemy.orm import Session

from grader.core.models import Event
from tests.factories import reference_sheet
from tests.integration.helpers import WAIT_LIMIT_S, case_runs

OTHER_COURSE = "other-course"  # tests/integration/conftest.py: the stack's second course

pytestmark = [pytest.mark.integration, pytest.mark.slow]


def _events(stack, submission_id: int) -> list[Event]:
    with Session(stack.engine) as session:
        return session.scalars(select(Event).where(Event.submission_id == submission_id).order_by(Event.id)).all()


def _instructor_of_another_course(stack, name: str):
    """An instructor (force_rerun is a staff power) of the stack's other course, so that the shared class the page
    tests read stays as they expect."""
    from grader.services.identity import accounts
    from grader.client import Client
    from grader.core.models import Course

    with Session(stack.engine) as session:
        course = session.scalar(select(Course).where(Course.name == OTHER_COURSE))
        user = accounts.get_or_create_user(session=session, course=course, name=name, role="instructor")
        token = accounts.create_token(session=session, user=user)
        session.commit()
    return Client(stack.url, token)


def test_a_grade_is_stored_between_cases_and_completed_after_the_cases_queued_meanwhile(stack):
    client = _instructor_of_another_course(stack, "olga")
    first = client.submit(reference_sheet() | {"student": "olga"})
    client.wait(first["id"], poll_s=0.5, timeout_s=WAIT_LIMIT_S)  # measured (or reused): the next sheet runs nothing
    sheet = reference_sheet() | {"student": "olga"}
    busy = client.submit(sheet, force_rerun=True)  # 9 case runs queued on cpu, the worker on the first
    reused = client.submit(sheet)  # every case finished in the POST: only its grade task is sent
    assert all(run.reused_from_id is not None and run.tries == 0 for run in case_runs(stack, reused["id"]))
    for submission_id in (busy["id"], reused["id"]):
        final = client.wait(submission_id, poll_s=0.5, timeout_s=WAIT_LIMIT_S)
        assert (final["status"], final["report_complete"]) == ("graded", True), final

    busy_runs_done = [e.id for e in _events(stack, busy["id"]) if e.case_run_id is not None and e.state == "done"]
    assert len(busy_runs_done) == 9
    states = {e.state: e.id for e in _events(stack, reused["id"])}
    # Event ids are the order the one worker wrote them: the reused sheet's grade came while the forced sheet's
    # cases were still being measured, and its lab check only after the last of them, without the reconciler
    # re-sending it (a "completing" event). No PNG is drawn by the service: the report's charts are drawn in the
    # browser from the stored arrays.
    assert states["graded"] < busy_runs_done[-1], (states, busy_runs_done)
    assert states["lab-check"] > busy_runs_done[-1], (states, busy_runs_done)
    assert "completing" not in states, states
