"""A worker starting on a host where a worker was killed re-sends the dead processes' runs first, before consuming; a
task that met an infrastructure error gives its run back for its retry."""

from __future__ import annotations

import os
import subprocess

import pytest
from sqlalchemy import select
from sqlalchemy.orm import Session

from rubric import load_rubric
from tests.factories import create_people, reference_sheet


def test_a_starting_worker_resends_the_runs_of_dead_processes_on_its_host_ahead_of_the_queue(tmp_path, monkeypatch):
    from grader.services.submissions import sheets, submit as submissions
    from grader.core import lifecycle
    from grader.core.db import make_engine, migrate
    from grader.core.models import CaseRun, Event, User, utcnow
    from grader.core.settings import settings
    from worker import tasks

    url = f"sqlite:///{tmp_path / 'grader.db'}"
    migrate(url)
    monkeypatch.setattr(settings, "database_url", url)
    gone = subprocess.Popen(["true"])
    gone.wait()
    engine = make_engine(url)
    with Session(engine) as session:
        create_people(session, course="l03", other_course="other")
        sheet = reference_sheet()
        submission = submissions.create_submission(session=session, student=session.scalar(select(User).filter_by(name="alice")),
                                            lesson="L03", sheet=sheet, force_rerun=False,
                                            specs=sheets.cases_to_run(sheets.parse_sheet(sheet), load_rubric("L03")))
        session.flush()
        killed, alive, elsewhere = submission.case_runs[:3]
        for run, host, pid in ((killed, lifecycle.HOST, gone.pid), (alive, lifecycle.HOST, os.getpid()),
                               (elsewhere, "another-host", gone.pid)):
            run.status, run.worker, run.worker_pid, run.started_at, run.tries = "running", host, pid, utcnow(), 1
        session.commit()
        ids = killed.id, alive.id, elsewhere.id
    sent = []
    monkeypatch.setattr(tasks.run_case_run, "apply_async", lambda **kwargs: sent.append(kwargs))

    tasks._rerun_what_died_here()

    assert sent == [{"args": [ids[0], 2], "queue": "cpu", "priority": lifecycle.RERUN_PRIORITY}]
    with Session(engine) as session:
        runs = {run.id: run for run in session.scalars(select(CaseRun).where(CaseRun.id.in_(ids)))}
        assert (runs[ids[0]].status, runs[ids[0]].delivery, runs[ids[0]].worker) == ("queued", 2, None)
        assert [(r.status, r.delivery) for r in (runs[ids[1]], runs[ids[2]])] == [("running", 1)] * 2  # alive; unknowable
        event = session.scalars(select(Event).where(Event.case_run_id == ids[0])).all()[-1]
        assert event.state == "requeued" and "seen by a worker starting there" in event.detail
    engine.dispose()


def test_a_run_whose_task_met_a_database_error_is_released_for_the_tasks_retry(tmp_path, monkeypatch):
    """The task's retry after an infrastructure error goes to whichever pool process is free: the run this process
    claimed goes back to queued under the same delivery, so the retry claims it (try 2) instead of finding it held
    by a live sibling and dropping it (left running until the reconciler or its lease)."""
    from sqlalchemy.exc import OperationalError

    from grader.services.submissions import sheets, submit as submissions
    from grader.core.db import make_engine, migrate
    from grader.core.models import CaseRun, Event, User
    from grader.core.settings import settings
    from worker import tasks

    url = f"sqlite:///{tmp_path / 'grader.db'}"
    migrate(url)
    monkeypatch.setattr(settings, "database_url", url)
    engine = make_engine(url)
    with Session(engine) as session:
        create_people(session, course="l03", other_course="other")
        sheet = reference_sheet()
        submission = submissions.create_submission(
            session=session, student=session.scalar(select(User).filter_by(name="alice")), lesson="L03",
            sheet=sheet, force_rerun=True, specs=sheets.cases_to_run(sheets.parse_sheet(sheet), load_rubric("L03")))
        session.commit()
        run_id = submission.case_runs[0].id

    def database_gone(spec, out_dir, **_):  # the database fails while the case runs (as the deadlock did)
        raise OperationalError("UPDATE case_runs", {}, Exception("deadlock detected"))

    monkeypatch.setattr(tasks.slot, "run_case_in_slot", database_gone)
    with pytest.raises(OperationalError):
        tasks.run_case_run.run(run_id, 1)
    with Session(engine) as session:
        run = session.get(CaseRun, run_id)
        assert (run.status, run.delivery, run.tries, run.worker_pid) == ("queued", 1, 1, None)
        event = session.scalars(select(Event).where(Event.case_run_id == run_id).order_by(Event.id)).all()[-1]
        assert event.state == "released" and "OperationalError" in event.detail, event.detail
    # The retry claims it: a second try under the same delivery (its case fails again here: the claim is the point).
    with pytest.raises(OperationalError):
        tasks.run_case_run.run(run_id, 1)
    with Session(engine) as session:
        run = session.get(CaseRun, run_id)
        assert (run.status, run.delivery, run.tries) == ("queued", 1, 2)
    engine.dispose()
