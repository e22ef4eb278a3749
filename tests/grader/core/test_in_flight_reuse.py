"""A case run whose case an earlier run is measuring right now waits for that measurement and reuses it, instead of
stepping the same case beside it (worker.case_run.await_measurement): a class at the deadline queues the same baseline
for every sheet, and two slots measuring one case cost twice the CPU for one result. The earlier run never waits for
a later one, and a run whose predecessor ends without a measurement measures itself."""

from __future__ import annotations

import threading
import time

import pytest
from sqlalchemy import select

from tests.factories import reference_sheet


def _post(api, who: str) -> int:
    response = api.client.post("/v1/submissions", json={"sheet": reference_sheet()}, headers=api.as_(who))
    assert response.status_code == 202, response.text
    return response.json()["id"]


def _n1(submission_id: int) -> tuple[int, int]:
    from grader.core.db import new_session
    from grader.core.models import CaseRun

    with new_session() as session:
        run = session.scalar(select(CaseRun).where(CaseRun.submission_id == submission_id, CaseRun.name == "N1"))
        return run.id, run.delivery


def _claim_and_key(case_run_id: int, delivery: int) -> str:
    """What a worker has done by the time it steps a case: claimed the run and committed its content key."""
    from grader.core import content_key, lifecycle
    from grader.core.db import new_session

    with new_session() as session:
        run, _ = lifecycle.claim(session=session, case_run_id=case_run_id, delivery=delivery)
        run.content_key = content_key.content_key(content_key.key_inputs(run.spec, backend=run.backend,
                                                                         precision=run.precision))
        session.commit()
        return run.content_key


def _finish_first(case_run_id: int, key: str, *, ok: bool, after_s: float) -> threading.Thread:
    """In another thread, after `after_s`: the earlier run ends, with its measurement stored (ok) or failed."""
    from grader.core.db import new_session
    from grader.core.models import CaseRun, Measurement, utcnow

    def finish():
        time.sleep(after_s)
        with new_session() as session:
            run = session.get(CaseRun, case_run_id)
            run.status, run.finished_at, run.lease_until = ("done" if ok else "failed"), utcnow(), None
            if ok:
                m = Measurement(content_key=key, key_inputs={}, case_run_id=run.id, backend="cpu",
                                provenance={"actual_backend": "cpu"}, metrics=None, artifact_dir="/measured/N1")
                session.add(m)
                session.flush()
                run.measurement_id, run.result_status = m.id, "ok"
            session.commit()

    thread = threading.Thread(target=finish)
    thread.start()
    return thread


class Stepped(Exception):
    pass


def _never_steps(spec, out_dir, **_):
    raise Stepped(spec.name)


def _process(case_run_id: int, delivery: int, run_case=_never_steps):
    from grader.core.db import new_session
    from worker.case_run import process_case_run

    with new_session() as session:
        return process_case_run(session=session, case_run_id=case_run_id, delivery=delivery, run_case=run_case)


def _run(case_run_id: int):
    from grader.core.db import new_session
    from grader.core.models import CaseRun

    with new_session() as session:
        return session.get(CaseRun, case_run_id)


def test_a_run_whose_case_is_being_measured_waits_and_reuses_that_measurement(api):
    first, later = _n1(_post(api, "alice")), _n1(_post(api, "bob"))
    key = _claim_and_key(*first)
    finisher = _finish_first(first[0], key, ok=True, after_s=0.5)
    started = time.monotonic()
    _process(*later)  # _never_steps: stepping the case again would raise
    waited = time.monotonic() - started
    finisher.join()
    run = _run(later[0])
    assert (run.status, run.reused_from_id, run.artifact_dir) == ("done", first[0], "/measured/N1")
    assert waited >= 0.4


def test_the_earlier_run_never_waits_for_a_later_one_and_a_failed_one_leaves_the_later_to_measure(api):
    from worker import case_run

    first, later = _n1(_post(api, "alice")), _n1(_post(api, "bob"))
    key = _claim_and_key(*first)
    _claim_and_key(*later)
    from grader.core.db import new_session

    with new_session() as session:
        earlier, second = session.get(case_run.CaseRun, first[0]), session.get(case_run.CaseRun, later[0])
        assert case_run.measuring_first(session=session, run=second).id == first[0]
        assert case_run.measuring_first(session=session, run=earlier) is None  # never the other way round
    finisher = _finish_first(first[0], key, ok=False, after_s=0.3)
    with new_session() as session:
        second = session.get(case_run.CaseRun, later[0])
        assert case_run.await_measurement(session=session, run=second) is None  # it failed: measure
    finisher.join()


def test_a_wait_is_bounded_and_a_forced_rerun_never_waits(api, monkeypatch):
    from grader.core.db import new_session
    from worker import case_run

    first, later = _n1(_post(api, "alice")), _n1(_post(api, "bob"))
    _claim_and_key(*first)
    _claim_and_key(*later)
    with new_session() as session:
        second = session.get(case_run.CaseRun, later[0])
        started = time.monotonic()
        assert case_run.await_measurement(session=session, run=second, limit_s=0.3) is None
        assert 0.3 <= time.monotonic() - started < 5
        second.submission.force_rerun = True
        monkeypatch.setattr(case_run, "measuring_first", lambda **_: pytest.fail("a forced re-run asked"))
        assert case_run.await_measurement(session=session, run=second) is None


def test_nobody_waits_for_a_run_held_by_a_dead_process(api):
    """A worker killed mid-case leaves its run 'running' under a live lease; a later run of that case measures at once
    instead of waiting out the bound (IN_FLIGHT_WAIT_MAX_S) for a measurement that never comes."""
    import subprocess
    import sys

    from grader.core.db import new_session
    from worker import case_run

    first, later = _n1(_post(api, "alice")), _n1(_post(api, "bob"))
    _claim_and_key(*first)
    _claim_and_key(*later)
    gone = subprocess.Popen([sys.executable, "-c", "pass"])
    gone.wait()  # reaped: its pid names no process
    with new_session() as session:
        second = session.get(case_run.CaseRun, later[0])
        assert case_run.measuring_first(session=session, run=second).id == first[0]  # its claimer (this process) lives
        session.get(case_run.CaseRun, first[0]).worker_pid = gone.pid
        session.commit()
        assert case_run.measuring_first(session=session, run=second) is None
        started = time.monotonic()
        assert case_run.await_measurement(session=session, run=second) is None
        assert time.monotonic() - started < 2


def test_nobody_waits_for_a_run_whose_lease_has_ended(api):
    """A run still marked running whose lease is over (its worker on another host gone, the reconciler not yet by)
    measures nothing any more: a later run of the case steps it at once instead of waiting out the bound
    (IN_FLIGHT_WAIT_MAX_S) for a measurement that never comes."""
    from datetime import timedelta

    from grader.core.db import new_session
    from grader.core.models import CaseRun, utcnow

    first, later = _n1(_post(api, "alice")), _n1(_post(api, "bob"))
    _claim_and_key(*first)  # claimed by this (living) process: only its lease says it is gone
    with new_session() as session:
        session.get(CaseRun, first[0]).lease_until = utcnow() - timedelta(seconds=1)
        session.commit()
    started = time.monotonic()
    with pytest.raises(Stepped):
        _process(*later)
    assert time.monotonic() - started < 5  # the wait's bound is IN_FLIGHT_WAIT_MAX_S (30 s)
    assert _run(later[0]).reused_from_id is None


def test_an_audit_rerun_measures_again_though_its_case_is_stored(api):
    """An audit re-run on the very backend and precision of a stored measurement (its content key the same) steps the
    case itself: neither a stored measurement nor the wait for one answers it."""
    from grader.core.audit import create_audit_rerun
    from grader.core.db import new_session
    from grader.core.models import CaseRun, User

    first = _n1(_post(api, "alice"))
    key = _claim_and_key(*first)
    _finish_first(first[0], key, ok=True, after_s=0).join()  # its measurement stored under `key`
    with new_session() as session:
        source = session.get(CaseRun, first[0])
        tess = session.scalars(select(User).where(User.name == "tess")).one()
        audit = create_audit_rerun(session, source=source, backend=source.backend, precision=source.precision,
                                   mode="isolated", user=tess)
        session.commit()
        audit_id, delivery = audit.id, audit.delivery
    with pytest.raises(Stepped):
        _process(audit_id, delivery)
    audit = _run(audit_id)
    assert (audit.content_key, audit.measurement_id, audit.reused_from_id) == (key, None, None)
