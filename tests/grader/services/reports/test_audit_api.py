"""The audit log's API on the real app in-process (SQLite): who may read and request, what is refused, and the
database refusing to change an entry. Real comparisons are tests/integration/test_audit.py."""

from __future__ import annotations

import pytest
from sqlalchemy.exc import DatabaseError

from tests.factories import audit_entry_for, reference_sheet


def _graded_like(api):
    """A submission and one 'done' case run as stored rows, plus one audit entry about it (no engine needed to
    test access rules and the append-only guard)."""
    from grader.core.db import new_session
    from grader.core.models import CaseRun

    response = api.client.post("/v1/submissions", json={"sheet": reference_sheet() | {"student": "alice"}},
                               headers=api.as_("alice"))
    assert response.status_code == 202, response.text
    submission = response.json()["id"]
    with new_session() as session:
        run = session.query(CaseRun).filter_by(submission_id=submission, name="N1").one()
        run.status, run.result_status, run.actual_backend = "done", "ok", "cpu"
        entry = audit_entry_for(run)
        session.add(entry)
        session.commit()
        return run.id, entry.id


def test_staff_read_the_log_and_students_do_not(api):
    run_id, entry_id = _graded_like(api)
    for who in ("tess", "prof"):
        listed = api.client.get("/v1/audit/entries", headers=api.as_(who))
        assert listed.status_code == 200 and [e["id"] for e in listed.json()] == [entry_id], who
    assert api.client.get("/v1/audit/entries", headers=api.as_("alice")).status_code == 403
    assert api.client.get(f"/v1/audit/entries/{entry_id}", headers=api.as_("alice")).status_code == 403
    assert api.client.get(f"/v1/audit/entries/{entry_id}", headers=api.as_("eve")).status_code == 404
    assert api.client.get("/v1/audit/entries", headers=api.as_("eve")).json() == []  # another course's instructor
    assert api.client.get(f"/v1/audit/entries/{2**63}", headers=api.as_("tess")).status_code in (404, 422)


def test_filters_select_and_bad_filters_name_the_field(api):
    _, entry_id = _graded_like(api)
    get = lambda q: api.client.get(f"/v1/audit/entries?{q}", headers=api.as_("tess"))  # noqa: E731
    assert [e["id"] for e in get("classification=numeric_drift&case=N1&backends=cpu,cpu").json()] == [entry_id]
    assert get("classification=identical").json() == [] and get("case=N2").json() == []
    assert get("backends=cpu,cuda").json() == [] and get("since=2999-01-01").json() == []
    for query, field in (("backends=cpu;cuda", "backends"), ("classification=weird", "classification"),
                         ("since=yesterday", "since"), ("lesson=L3", "lesson"), ("colour=red", "colour")):
        response = get(query)
        assert response.status_code == 422, query
        assert any(field in e["field"] for e in response.json()["errors"]), (query, response.json())


def test_csv_export_has_a_row_per_entry(api):
    _, entry_id = _graded_like(api)
    response = api.client.get("/v1/audit/entries.csv", headers=api.as_("prof"))
    assert response.status_code == 200 and response.headers["content-type"].startswith("text/csv")
    header, row = response.text.strip().splitlines()
    assert header.startswith("entry_id,created_at_utc,lesson,case")
    assert row.startswith(f"{entry_id},") and "numeric_drift" in row and "cpu/64/warm" in row


def test_a_rerun_with_no_worker_on_the_queue_is_refused_at_once_and_nothing_is_stored(api):
    from grader.core.db import new_session
    from grader.core.models import CaseRun

    run_id, _ = _graded_like(api)
    sent = len(api.sent)
    response = api.client.post(f"/v1/case-runs/{run_id}/audit-reruns", json={"backend": "cuda"},
                               headers=api.as_("tess"))
    assert response.status_code == 409 and "no worker is listening on queue 'cuda'" in response.json()["detail"]
    with new_session() as session:
        assert session.query(CaseRun).filter_by(purpose="audit").count() == 0
    assert len(api.sent) == sent
    refused = api.client.post(f"/v1/case-runs/{run_id}/audit-reruns", json={"backend": "tpu"}, headers=api.as_("tess"))
    assert refused.status_code == 422 and refused.json()["errors"][0]["field"].endswith("backend")
    assert api.client.post(f"/v1/case-runs/{run_id}/audit-reruns", json={}, headers=api.as_("alice")).status_code == 403
    assert api.client.post(f"/v1/case-runs/{run_id}/audit-reruns", json={}, headers=api.as_("eve")).status_code == 404


def test_an_accepted_rerun_is_an_audit_run_that_never_counts_in_the_grade(api):
    from grader.core.db import new_session
    from grader.core.models import Submission

    run_id, _ = _graded_like(api)
    response = api.client.post(f"/v1/case-runs/{run_id}/audit-reruns", json={"precision": "64", "mode": "isolated"},
                               headers=api.as_("prof"))
    assert response.status_code == 202, response.text
    body = response.json()
    assert (body["purpose"], body["precision"], body["mode"], body["source_case_run_id"]) == ("audit", "64", "isolated", run_id)
    assert body["spec"]["precision"] == "64" and body["name"] == "audit-1:N1"
    assert api.sent[-1] == (body["id"], 1, "cpu")
    with new_session() as session:
        from grader.core.models import CaseRun

        submission = session.get(Submission, session.get(CaseRun, run_id).submission_id)
        assert body["id"] not in [r.id for r in submission.case_runs]
        assert [r.id for r in submission.audit_runs] == [body["id"]]


def test_the_database_refuses_to_change_or_delete_an_entry(api):
    from grader.core.db import new_session
    from grader.core.models import AuditEntry

    _, entry_id = _graded_like(api)
    with new_session() as session:
        entry = session.get(AuditEntry, entry_id)
        entry.classification = "identical"
        with pytest.raises(DatabaseError, match="append-only"):
            session.commit()
        session.rollback()
        session.delete(session.get(AuditEntry, entry_id))
        with pytest.raises(DatabaseError, match="append-only"):
            session.commit()
        session.rollback()
        assert session.get(AuditEntry, entry_id).classification == "numeric_drift"


def test_the_audit_pages_for_staff_only(api):
    run_id, entry_id = _graded_like(api)
    api.client.post("/sign-in", data={"token": api.tokens["tess"], "next": "/audit"})
    page = api.client.get("/audit")
    assert page.status_code == 200 and f'id="entry-{entry_id}"' in page.text and "numeric drift" in page.text
    one = api.client.get(f"/audit/{entry_id}")
    assert one.status_code == 200 and "cpu/64/warm" in one.text and "Provenance side by side" in one.text
    bad = api.client.get("/audit?backends=cpu;cuda")
    assert bad.status_code == 422 and "backends" in bad.text
    refused = api.client.post("/audit/reruns", data={"case_run_id": run_id, "backend": "cuda"}, follow_redirects=True)
    assert "Refused: no worker is listening on queue" in refused.text
    csv = api.client.get("/audit.csv")
    assert csv.status_code == 200 and csv.text.startswith("entry_id,")
    api.client.post("/sign-out")
    api.client.post("/sign-in", data={"token": api.tokens["alice"], "next": "/audit"})
    assert api.client.get("/audit").status_code == 404
    assert api.client.get(f"/audit/{entry_id}").status_code == 404
