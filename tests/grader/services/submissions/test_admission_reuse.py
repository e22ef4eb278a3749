"""Reuse decided when a submission is stored: a case whose content key already has a measurement is finished in the
request, and a submission with nothing left to run sends only its grade task (no broker round trip per case)."""

from __future__ import annotations

import pytest
from sqlalchemy import select

from rubric import load_rubric
from tests.factories import reference_sheet


@pytest.fixture
def grades_sent(api, monkeypatch) -> list[int]:
    from grader import dispatch

    sent: list[int] = []
    monkeypatch.setattr(dispatch, "send_grade", sent.append)
    return sent


def store_measurements(names: set[str] | None = None) -> dict[str, int]:
    """bob's earlier submission of the reference sheet, its cases (or those named) done and stored as Measurements
    under the worker's content key, as a worker that measured them would have left them; their ids by case name."""
    from grader.services.identity import accounts
    from grader.services.submissions import sheets, submit as submissions
    from grader.core.db import new_session
    from grader.core.models import Measurement, User
    from grader.core import content_key as reuse

    out = {}
    with new_session() as session:
        bob = session.scalar(select(User).where(User.name == "bob"))
        specs = sheets.cases_to_run(sheets.parse_sheet(reference_sheet()), load_rubric("L03"))
        earlier = submissions.create_submission(session=session, student=bob, lesson="L03", sheet=reference_sheet(),
                                         specs=specs, force_rerun=False)
        session.flush()
        for spec, run in zip(specs, earlier.case_runs):
            if names is not None and spec.name not in names:
                continue
            inputs = reuse.key_inputs(run.spec, backend=run.backend, precision=run.precision)
            run.status, run.result_status, run.artifact_dir = "done", "ok", f"/stored/{spec.name}"
            m = Measurement(content_key=reuse.content_key(inputs), key_inputs=inputs, case_run_id=run.id,
                            backend="cpu", provenance={"actual_backend": "cpu"}, metrics=None,
                            artifact_dir=run.artifact_dir)
            session.add(m)
            session.flush()
            out[spec.name] = m.id
        session.commit()
    return out


def post(api, who="alice", **options) -> dict:
    response = api.client.post("/v1/submissions", json={"sheet": reference_sheet(), **options},
                               headers=api.as_(who))
    assert response.status_code == 202, response.text
    return response.json()


def runs_of(submission_id: int):
    from grader.core.db import new_session
    from grader.core.models import CaseRun

    with new_session() as session:
        return {r.name: r for r in session.scalars(select(CaseRun).where(CaseRun.submission_id == submission_id))}


def test_a_submission_whose_every_case_is_stored_sends_only_its_grade_task(api, grades_sent):
    stored = store_measurements()
    row = post(api)
    assert row["status"] == "grading" and row["progress"]["done"] == row["progress"]["total"] == len(stored) == 9
    assert api.sent == [] and grades_sent == [row["id"]]
    runs = runs_of(row["id"])
    assert {name: run.measurement_id for name, run in runs.items()} == stored
    assert all(run.status == "done" and run.result_status == "ok" and run.tries == 0 for run in runs.values())
    assert runs["N4"].artifact_dir == "/stored/N4" and runs["N4"].reused_from_id is not None


def test_only_the_cases_without_a_stored_measurement_are_queued(api, grades_sent):
    store_measurements({"N1", "N2"})
    row = post(api)
    assert row["status"] == "running" and row["progress"]["done"] == 2 and grades_sent == []
    names = {run.id: name for name, run in runs_of(row["id"]).items()}
    assert sorted(names[case_run_id] for case_run_id, _attempt, _backend in api.sent) == sorted(
        set(names.values()) - {"N1", "N2"})


def test_force_rerun_queues_every_case_even_when_stored(api, grades_sent):
    store_measurements()
    row = post(api, "prof", force_rerun=True)  # a staff power (test_fair_queues)
    assert row["progress"]["queued"] == len(api.sent) == 9 and grades_sent == []


def test_a_measurement_under_other_engine_versions_is_not_reused(api, grades_sent, monkeypatch):
    from grader.core import content_key as reuse

    store_measurements()
    monkeypatch.setattr(reuse, "engine_versions", lambda: {"genesis-world": "9.9.9", "quadrants": "x", "torch": "x"})
    row = post(api)
    assert row["progress"]["queued"] == len(api.sent) == 9 and grades_sent == []
