"""Two case runs of one submission finishing at once on two case slots, on PostgreSQL: the submission's lock that
serializes finishers (grader.core.lifecycle.lock_submission) must not deadlock with the key-share lock an insert
referencing the submission takes (an event). Seen in the benchmark on 2026-11-27: both finishers' SELECT ... FOR UPDATE
on the submission waited for each other ('deadlock detected ... while locking tuple in relation "submissions"'), one
task failed, and its retry, on the sibling slot, found the run held by a live process and dropped it."""

from __future__ import annotations

import threading

import pytest
from sqlalchemy import select
from sqlalchemy.orm import Session

from tests import services
from tests.factories import create_people, reference_sheet

pytestmark = pytest.mark.integration


def test_two_finishers_of_one_submission_each_holding_an_event_both_take_its_lock():
    from rubric import load_rubric

    from grader.core import lifecycle
    from grader.core.db import make_engine, migrate
    from grader.core.models import Event, User
    from grader.services.submissions import sheets, submit as submissions

    with services.postgres_database() as url:
        migrate(url)
        engine = make_engine(url)
        try:
            with Session(engine) as session:
                create_people(session, course="l03-locks", other_course="other")
                sheet = reference_sheet()
                submission = submissions.create_submission(
                    session=session, student=session.scalar(select(User).filter_by(name="alice")), lesson="L03",
                    sheet=sheet, force_rerun=False,
                    specs=sheets.cases_to_run(sheets.parse_sheet(sheet), load_rubric("L03")))
                session.commit()
                submission_id, runs = submission.id, [run.id for run in submission.case_runs[:2]]
            both_wrote = threading.Barrier(2, timeout=30)
            outcome: dict[int, str] = {}

            def finisher(run_id: int) -> None:
                with Session(engine) as session:
                    try:
                        session.add(Event(submission_id=submission_id, case_run_id=run_id, state="x", detail="y"))
                        session.flush()  # the event's foreign key takes a key-share lock on the submission's row
                        both_wrote.wait()
                        lifecycle.lock_submission(session, submission_id)
                        session.rollback()
                        outcome[run_id] = "locked"
                    except Exception as exc:  # noqa: BLE001 - what each finisher met is the finding
                        outcome[run_id] = f"{type(exc).__name__}: {str(exc).splitlines()[0]}"

            threads = [threading.Thread(target=finisher, args=(run_id,)) for run_id in runs]
            for thread in threads:
                thread.start()
            for thread in threads:
                thread.join(60)
            assert outcome == {run_id: "locked" for run_id in runs}, outcome
        finally:
            engine.dispose()
