"""A case process runs under a memory limit: a real Genesis case process held to a limit below what importing Genesis
takes is stopped, and its case fails with its own reason ("memory limit exceeded: N MB"), not a time-out or a crash;
the worker stores it like any failure and the report shows the reason. A warm process stopped so is replaced."""

from __future__ import annotations

import pytest

from rubric import get_case
from tests.factories import reference_sheet
from tests.grader.conftest import api  # noqa: F401 - the fixture, for the report test below
from worker.case_process import WarmCaseProcess, run_case

pytestmark = pytest.mark.slow

SMALL_MB = 300  # a case process holds ~790 MB once Genesis and torch are imported (docs/operator.md)


def test_an_isolated_case_over_the_limit_fails_with_its_own_reason(tmp_path):
    result = run_case(get_case("N1"), tmp_path / "N1", mode="isolated", memory_limit_mb=SMALL_MB)
    assert result.status == "failed" and not result.arrays
    assert result.error.startswith(f"memory limit exceeded: {SMALL_MB} MB (the case process held "), result.error
    assert "time limit" not in result.error and "case process failed" not in result.error


def test_a_warm_process_stopped_for_memory_is_replaced_for_the_next_case(tmp_path):
    with WarmCaseProcess() as warm:
        over = warm.run(get_case("N1"), tmp_path / "over", memory_limit_mb=SMALL_MB)
        assert over.status == "failed" and over.error.startswith("memory limit exceeded"), over.error
        again = warm.run(get_case("N1"), tmp_path / "again", memory_limit_mb=0)
        assert again.ok, again.error
        assert warm.processes_started == 2


def test_the_setting_and_the_case_process_default_agree():
    from grader.core.settings import Settings
    from worker.case_process import DEFAULT_MEMORY_LIMIT_MB

    assert Settings.model_fields["case_memory_limit_mb"].default == DEFAULT_MEMORY_LIMIT_MB


def test_the_worker_stores_the_reason_and_the_report_shows_it(api, monkeypatch):  # noqa: F811 - imported fixture
    from grader.core.db import new_session
    from grader.core.models import CaseRun
    from grader.ops import failure_reason
    from grader.core.settings import settings
    from worker.case_run import process_case_run
    from worker.slot import run_case_in_slot

    monkeypatch.setattr(settings, "case_memory_limit_mb", SMALL_MB)  # CASE_MEMORY_LIMIT_MB=300 on this worker
    monkeypatch.setattr(settings, "execution_mode", "isolated")

    response = api.client.post("/v1/submissions", json={"sheet": reference_sheet()}, headers=api.as_("alice"))
    assert response.status_code == 202, response.text
    sid = response.json()["id"]
    case_run_id, delivery, _ = next(sent for sent in api.sent)
    with new_session() as session:
        process_case_run(session=session, case_run_id=case_run_id, delivery=delivery, run_case=run_case_in_slot)
    with new_session() as session:
        run = session.get(CaseRun, case_run_id)
        assert run.status == "failed" and run.error.startswith(f"memory limit exceeded: {SMALL_MB} MB")
        assert failure_reason(run) == "memory_limit"
        name = run.name
    rows = api.client.get(f"/v1/submissions/{sid}/case-runs", headers=api.as_("alice")).json()
    assert next(r for r in rows if r["name"] == name)["error"].startswith("memory limit exceeded")
    page = api.client.get(f"/submissions/{sid}", headers=api.as_("alice")).text
    assert f"memory limit exceeded: {SMALL_MB} MB" in page
    stderr = api.client.get(f"/v1/submissions/{sid}/case-runs/{name}/files/stderr.txt", headers=api.as_("alice"))
    assert stderr.status_code == 200  # what it printed before it was stopped is kept, in the database
