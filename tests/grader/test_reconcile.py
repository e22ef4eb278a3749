"""Nothing is lost: a broker outage at submit time leaves durable queued runs that the reconciler re-sends."""

from __future__ import annotations

from datetime import timedelta

from click.testing import CliRunner
from sqlalchemy import update

from tests.factories import heavy_imports, reference_sheet


def test_broker_down_at_submit_keeps_the_runs_and_the_reconciler_resends_them(api, monkeypatch):
    from grader import dispatch
    from grader.cli.service import reconcile
    from grader.core.db import new_session
    from grader.models import CaseRun, utcnow
    from grader.settings import settings

    def broker_down(*args):
        raise ConnectionError("broker unreachable")

    monkeypatch.setattr(dispatch, "send_case_run", broker_down)
    response = api.client.post("/v1/submissions", json={"sheet": reference_sheet()}, headers=api.as_("alice"))
    assert response.status_code == 202
    submission_id = response.json()["id"]
    runs = api.client.get(f"/v1/submissions/{submission_id}/case-runs", headers=api.as_("alice")).json()
    assert runs and all(r["status"] == "queued" and r["attempt"] == 1 for r in runs)

    # The broker is back; the fixture records every message sent from here on.
    monkeypatch.setattr(dispatch, "send_case_run", lambda *args, **options: api.sent.append((*args, options)))
    early = CliRunner().invoke(reconcile, [])
    assert early.exit_code == 0, early.output
    assert api.sent == [] and early.output == ""  # not yet past the queue lease: nothing is re-sent

    with new_session() as session:  # the queue lease passes without a worker ever seeing the messages
        session.execute(update(CaseRun).where(CaseRun.submission_id == submission_id)
                        .values(queued_at=utcnow() - timedelta(seconds=settings.queue_lease_s + 1)))
        session.commit()
    late = CliRunner().invoke(reconcile, [])
    assert late.exit_code == 0, late.output
    assert late.output.strip() == f"re-sent {len(runs)} case runs, 0 gradings"
    # Each case run sent exactly once, under its new attempt number, to the queue of its own backend.
    # Re-sent ahead of the runs queued since (dispatch.RESENT_PRIORITY).
    assert sorted(api.sent) == sorted((r["id"], 2, r["backend"], {"priority": dispatch.RESENT_PRIORITY}) for r in runs)
    assert {r["backend"] for r in runs} == {"cpu"}
    after = api.client.get(f"/v1/submissions/{submission_id}/case-runs", headers=api.as_("alice")).json()
    assert all(r["status"] == "queued" and r["attempt"] == 2 for r in after)
    events = api.client.get(f"/v1/submissions/{submission_id}/events", headers=api.as_("alice")).json()
    assert [e["state"] for e in events].count("requeued") == len(runs)


def test_the_api_never_imports_genesis_or_torch():
    assert heavy_imports(["grader.main"], watch=("genesis", "torch", "celery")) == []
