"""Nothing is lost: a broker outage at submit time leaves durable queued runs that the reconciler re-sends."""

from __future__ import annotations

from datetime import timedelta

from tests.factories import heavy_imports, reference_sheet


def test_broker_down_at_submit_keeps_the_runs_and_the_reconciler_resends_them(api, monkeypatch):
    from grader import dispatch
    from grader.core.db import new_session
    from grader.models import utcnow
    from grader.reconcile import find_and_requeue
    from grader.settings import settings

    def broker_down(*args):
        raise ConnectionError("broker unreachable")

    monkeypatch.setattr(dispatch, "send_case_run", broker_down)
    response = api.client.post("/v1/submissions", json={"sheet": reference_sheet()}, headers=api.as_("alice"))
    assert response.status_code == 202
    total = response.json()["progress"]["total"]
    with new_session() as session:
        assert find_and_requeue(session=session).case_runs == []  # not yet past the queue lease
        later = utcnow() + timedelta(seconds=settings.queue_lease_s + 1)
        todo = find_and_requeue(session=session, now=later)
    assert len(todo.case_runs) == total and {attempt for _, attempt, _ in todo.case_runs} == {2}
    events = api.client.get(f"/v1/submissions/{response.json()['id']}/events", headers=api.as_("alice")).json()
    assert [e["state"] for e in events].count("requeued") == total


def test_the_api_never_imports_genesis_or_torch():
    assert heavy_imports(["grader.main"], watch=("genesis", "torch", "celery")) == []
