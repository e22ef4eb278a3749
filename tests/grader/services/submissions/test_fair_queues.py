"""One student cannot fill the queue (issue 26): a backend and a forced re-run are staff powers, a backend no worker
listens on is refused at once, a student's waiting runs are capped, students' runs interleave, and audit re-runs
are limited and never queued twice. On the real app (tests/grader/conftest.py), enqueueing recorded."""

from __future__ import annotations

import pytest
from sqlalchemy import func, select, update

from tests.factories import reference_sheet


def stored() -> tuple[int, int]:
    from grader.core.db import new_session
    from grader.core.models import CaseRun, Submission

    with new_session() as session:
        return (session.scalar(select(func.count()).select_from(Submission)),
                session.scalar(select(func.count()).select_from(CaseRun)))


def submit(api, who="alice", **options):
    return api.client.post("/v1/submissions", json={"sheet": reference_sheet(), **options}, headers=api.as_(who))


def fields(response) -> set[str]:
    return {e["field"] for e in response.json()["errors"]}


@pytest.mark.parametrize("options, field", [
    ({"backend": "rocm"}, "backend"),
    ({"backend": "cpu"}, "backend"),
    ({"force_rerun": True}, "force_rerun"),
])
def test_a_student_may_not_choose_a_backend_or_force_a_rerun(api, options, field):
    response = submit(api, **options)
    assert response.status_code == 403, response.text
    assert field in fields(response) and "staff" in response.text
    assert stored() == (0, 0) and api.sent == []


def test_a_student_may_not_name_a_backend_in_a_config(api):
    sheet = reference_sheet()
    sheet["configs"]["table_exercise"]["backend"] = "cuda"
    response = api.client.post("/v1/submissions", json={"sheet": sheet}, headers=api.as_("alice"))
    assert response.status_code == 403, response.text
    assert fields(response) == {"sheet.configs.table_exercise.backend"}
    assert stored() == (0, 0) and api.sent == []


def test_a_backend_no_worker_listens_on_is_refused_at_once(api):
    """The embedded broker's one worker consumes cpu and grade only: a rocm request would wait forever."""
    response = submit(api, who="prof", backend="rocm")
    assert response.status_code == 409, response.text
    assert "no worker is listening on queue 'rocm'" in response.json()["detail"] and fields(response) == {"backend"}
    assert stored() == (0, 0) and api.sent == []


def test_staff_choose_a_backend_a_worker_listens_on_and_it_goes_to_that_queue_only(api, monkeypatch):
    from grader import dispatch

    monkeypatch.setattr(dispatch, "queue_listeners", lambda queue, **_: ["gpu-1"] if queue == "rocm" else [])
    response = submit(api, who="prof", backend="rocm", force_rerun=True)
    assert response.status_code == 202, response.text
    assert api.sent and {backend for _, _, backend in api.sent} == {"rocm"}


def test_a_students_waiting_runs_are_capped_and_freed_as_they_finish(api, monkeypatch):
    from grader.core.db import new_session
    from grader.core.models import CaseRun
    from grader.core.settings import settings

    monkeypatch.setattr(settings, "student_waiting_runs_max", 12)
    first = submit(api)
    assert first.status_code == 202 and len(api.sent) == 9
    second = submit(api)
    assert second.status_code == 409, second.text
    rule = second.json()["errors"][0]["rule"]
    assert "9 of your case runs are still waiting or running" in rule and "at most 12" in rule
    assert stored() == (1, 9) and len(api.sent) == 9  # nothing of the refused sheet stored or sent
    assert submit(api, who="bob").status_code == 202  # the cap is each student's own
    with new_session() as session:
        session.execute(update(CaseRun).where(CaseRun.submission_id == first.json()["id"]).values(status="done"))
        session.commit()
    assert submit(api).status_code == 202


def test_students_runs_interleave_by_how_many_of_their_own_wait_ahead(api, monkeypatch):
    from grader.core.settings import settings

    monkeypatch.setattr(settings, "student_waiting_runs_max", 100)
    assert submit(api, who="alice").status_code == 202
    alice_first = api.priorities[:]
    assert submit(api, who="bob").status_code == 202
    bob = api.priorities[len(alice_first):]
    assert submit(api, who="alice").status_code == 202
    alice_second = api.priorities[len(alice_first) + len(bob):]
    assert alice_first == bob == [4, 5, 6, 7, 8, 8, 8, 8, 8]
    assert alice_second == [8] * 9  # behind bob's first runs: alice already has nine waiting


def test_audit_reruns_are_not_queued_twice_and_are_rate_limited(api, monkeypatch):
    from grader.core.db import new_session
    from grader.core.models import CaseRun
    from grader.core.settings import settings

    monkeypatch.setattr(settings, "rate_limit_audit_reruns", "2/hour")
    assert submit(api).status_code == 202
    with new_session() as session:
        runs = session.scalars(select(CaseRun).order_by(CaseRun.id)).all()
        for run in runs[:3]:
            run.status, run.result_status = "done", "ok"
        session.commit()
        ids = [run.id for run in runs[:3]]

    def rerun(case_run_id, who="tess"):
        return api.client.post(f"/v1/case-runs/{case_run_id}/audit-reruns", headers=api.as_(who),
                               json={"backend": "cpu", "precision": "64", "mode": "isolated"})

    sent = len(api.sent)
    first = rerun(ids[0])
    assert first.status_code == 202, first.text
    again = rerun(ids[0])
    assert again.status_code == 409, again.text
    assert f"audit re-run {first.json()['id']}" in again.json()["detail"] and len(api.sent) == sent + 1
    assert rerun(ids[1]).status_code == 202
    limited = rerun(ids[2])
    assert limited.status_code == 429 and limited.headers["Retry-After"], limited.text
    assert "at most 2 per 1 hour" in limited.text and len(api.sent) == sent + 2
    assert rerun(ids[2], who="prof").status_code == 202  # each staff member's own count
