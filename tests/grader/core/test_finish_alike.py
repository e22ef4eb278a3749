"""A new measurement finishes every queued run of the same case at once (grader.core.lifecycle.finish_alike): a class
at the deadline queues the same case for many sheets, and each of those runs would otherwise take a case slot in
turn only to reuse it. A run already claimed, a forced re-run and another case stay as they are; a submission whose
last run this finishes moves to grading; the finished run's own message is then dropped without stepping anything."""

from __future__ import annotations

from sqlalchemy import select, update

from tests.grader.core.test_in_flight_reuse import _claim_and_key, _finish_first, _n1, _post, _process, _run


def _runs(submission_id: int) -> dict[str, tuple[int, str]]:
    from grader.core.db import new_session
    from grader.core.models import CaseRun

    with new_session() as session:
        return {r.name: (r.id, r.status) for r in session.scalars(
            select(CaseRun).where(CaseRun.submission_id == submission_id))}


def _measure_n1(submission_id: int) -> int:
    """The submission's N1 claimed and measured (its measurement stored, as store_result stores it)."""
    first = _n1(submission_id)
    key = _claim_and_key(*first)
    _finish_first(first[0], key, ok=True, after_s=0).join()
    return first[0]


def test_a_new_measurement_finishes_the_queued_runs_of_its_case(api):
    from grader.core import lifecycle
    from grader.core.db import new_session
    from grader.core.models import Event, Submission

    measured_sub, waiting_sub, claimed_sub, forced_sub = (_post(api, who) for who in ("alice", "bob", "alice", "bob"))
    claimed = _n1(claimed_sub)
    _claim_and_key(*claimed)  # a worker holds it: it reuses the measurement itself (worker.case_run)
    with new_session() as session:
        session.execute(update(Submission).where(Submission.id == forced_sub).values(force_rerun=True))
        session.commit()
    first = _measure_n1(measured_sub)

    with new_session() as session:
        assert lifecycle.finish_alike(session, first) == []  # every other run of bob's sheet still waits

    waiting = _run(_n1(waiting_sub)[0])
    assert (waiting.status, waiting.reused_from_id, waiting.artifact_dir) == ("done", first, "/measured/N1")
    with new_session() as session:
        details = session.scalars(select(Event.detail).where(Event.case_run_id == waiting.id)).all()
    assert any("finished when it was measured" in d for d in details), details
    assert {name: status for name, (_, status) in _runs(waiting_sub).items() if name != "N1"} == \
        {name: "queued" for name in _runs(waiting_sub) if name != "N1"}  # other cases are not N1's to finish
    assert _run(claimed[0]).status == "running"
    assert _run(_n1(forced_sub)[0]).status == "queued"  # a forced re-run measures again

    assert _process(*_n1(waiting_sub)) is None  # its message, arriving now, steps nothing (_never_steps would raise)


def test_the_last_queued_run_finished_moves_its_submission_to_grading(api):
    from grader.core import lifecycle
    from grader.core.db import new_session
    from grader.core.models import CaseRun, Submission

    measured_sub, waiting_sub = _post(api, "alice"), _post(api, "bob")
    with new_session() as session:  # every case of bob's sheet but N1 already finished
        session.execute(update(CaseRun).where(CaseRun.submission_id == waiting_sub, CaseRun.name != "N1")
                        .values(status="done", result_status="ok"))
        session.execute(update(Submission).where(Submission.id == waiting_sub).values(status="running"))
        session.commit()
    first = _measure_n1(measured_sub)

    with new_session() as session:
        assert lifecycle.finish_alike(session, first) == [waiting_sub]
        assert session.get(Submission, waiting_sub).status == "grading"
        assert lifecycle.finish_alike(session, first) == []  # once: nothing queued is left


def test_a_failed_run_finishes_nothing(api):
    from grader.core import lifecycle
    from grader.core.db import new_session

    failed_sub, waiting_sub = _post(api, "alice"), _post(api, "bob")
    failed = _n1(failed_sub)
    _finish_first(failed[0], _claim_and_key(*failed), ok=False, after_s=0).join()
    with new_session() as session:
        assert lifecycle.finish_alike(session, failed[0]) == []
    assert _run(_n1(waiting_sub)[0]).status == "queued"


def test_a_queued_audit_rerun_of_the_case_is_left_to_measure_again(api):
    """An audit re-run of the same case on the same backend and precision (its content key the measurement's) exists
    to measure again: a grading run's new measurement finishes bob's queued grading run of the case, not the audit."""
    from grader.core import lifecycle
    from grader.core.audit import create_audit_rerun
    from grader.core.db import new_session
    from grader.core.models import CaseRun, User

    measured_sub, audited_sub = _post(api, "alice"), _post(api, "bob")
    with new_session() as session:
        source = session.get(CaseRun, _n1(audited_sub)[0])
        tess = session.scalars(select(User).where(User.name == "tess")).one()
        audit_id = create_audit_rerun(session, source=source, backend=source.backend, precision=source.precision,
                                      mode="isolated", user=tess).id
        session.commit()
    first = _measure_n1(measured_sub)

    with new_session() as session:
        lifecycle.finish_alike(session, first)
    assert _run(_n1(audited_sub)[0]).reused_from_id == first  # the grading run of the same case: finished on it
    audit = _run(audit_id)
    assert (audit.status, audit.measurement_id, audit.reused_from_id) == ("queued", None, None)
