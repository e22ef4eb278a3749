"""The backend-discrepancy audit on the real stack: audit re-runs sent over HTTP to the Celery worker on Redis,
measured by real Genesis on the CPU, compared and logged in PostgreSQL, read in a real browser; and the database
refusing to change or delete an entry.

No GPU is lent to these machines' test runs: CPU precision 32 against 64 is the pair that really differs, and
isolated against warm execution is the pair that must not."""

from __future__ import annotations

import time

import pytest
from sqlalchemy import select, text
from sqlalchemy.exc import DatabaseError
from sqlalchemy.orm import Session

from grader.core.models import AuditEntry
from tests.integration.helpers import SHOTS, images_decoded, signed_in, wait_until

pytestmark = [pytest.mark.integration, pytest.mark.slow]


def _runs_by_name(stack, submission_id: int) -> dict[str, dict]:
    return {r["name"]: r for r in stack.client("tess").case_runs(submission_id)}


def _request(stack, case_run_id: int, who: str = "tess", **body):
    return stack.client(who).http.post(f"/case-runs/{case_run_id}/audit-reruns", json=body)


def _entry_for(stack, audit_run_id: int) -> dict:
    def found():
        with Session(stack.engine) as session:
            return session.scalar(select(AuditEntry.id).where(AuditEntry.right_case_run_id == audit_run_id))
    entry_id = wait_until(found, f"the audit entry of case run {audit_run_id}")
    response = stack.client("tess").http.get(f"/audit/entries/{entry_id}")
    assert response.status_code == 200, response.text
    return response.json()


@pytest.fixture(scope="module")
def source_runs(stack, graded):
    """The stored grading runs of Alice's first graded submission, by case name (the measurements that the
    re-runs re-measure; most were measured once and reused, so follow each to its own measuring run)."""
    runs = _runs_by_name(stack, graded["alice_first"]["id"])
    return {name: r["reused_from_id"] or r["id"] for name, r in runs.items()}


def test_a_request_for_a_backend_no_worker_listens_on_is_refused_at_once(stack, source_runs):
    started = time.monotonic()
    response = _request(stack, source_runs["N1"], backend="cuda")
    elapsed = time.monotonic() - started
    assert response.status_code == 409, response.text
    assert "no worker is listening on queue 'cuda'" in response.json()["detail"]
    assert elapsed < 10, f"the refusal took {elapsed:.1f} s"
    assert _request(stack, source_runs["N1"], who="alice").status_code == 403
    assert _request(stack, source_runs["N1"], who="eve").status_code == 404


def test_isolated_against_warm_for_n1_to_n4_is_identical(stack, source_runs):
    requested = {}
    for name in ("N1", "N2", "N3", "N4"):
        response = _request(stack, source_runs[name], mode="isolated")
        assert response.status_code == 202, response.text
        assert response.json()["purpose"] == "audit"
        requested[name] = response.json()["id"]
    relations = {}
    for name, run_id in requested.items():
        entry = _entry_for(stack, run_id)
        relations |= {r["id"]: r for r in entry["comparison"]["relations"]}
        assert (entry["left_variant"], entry["right_variant"]) == ("cpu/32/warm", "cpu/32/isolated"), entry
        assert entry["classification"] == "identical", (name, entry["summary"])
        assert all(a["max_abs"] == 0 for a in entry["comparison"]["arrays"]), name
        assert entry["left_provenance"]["execution_mode"] == "warm"
        assert entry["right_provenance"]["execution_mode"] == "isolated"
    # The lesson's relations between cases, judged on each side once both variants hold the cases they need.
    for relation in ("substeps_lower_proxy.N1_N2", "substeps_lower_proxy.N3_N4", "n1_n4_agree"):
        assert relations[relation]["left"] is relations[relation]["right"] is True, relations.get(relation)
        assert relations[relation]["changed"] is False


def test_precision_64_against_32_on_the_cpu_differs_and_is_classified_with_figures(browser, stack, source_runs):
    response = _request(stack, source_runs["N1"], precision="64")
    assert response.status_code == 202, response.text
    entry = _entry_for(stack, response.json()["id"])
    assert (entry["left_variant"], entry["right_variant"]) == ("cpu/32/warm", "cpu/64/warm")
    assert entry["classification"] != "identical", entry["summary"]
    assert entry["classification"] in ("within_tolerance", "numeric_drift", "relation_changed")
    arrays = {a["name"]: a for a in entry["comparison"]["arrays"]}
    assert max(a["max_abs"] for a in arrays.values()) > 0
    assert entry["right_provenance"]["precision"] == "64" and entry["left_provenance"]["precision"] == "32"
    assert entry["figures"], "an entry that compared arrays has its overlaid figures"
    print(f"\nN1 cpu 32 vs 64: {entry['classification']}: {entry['summary']}")

    # The auditor finds it on the page, filtered by class, with the overlaid figures and both provenances.
    page = signed_in(browser, stack, "tess")
    page.click("text=Audit log")
    page.select_option("select[name=classification]", entry["classification"])
    page.click("#filters button[type=submit]")
    assert page.locator(f"#entry-{entry['id']}").count() == 1
    assert page.locator("#entries tbody tr").count() >= 1
    page.click(f"#entry-{entry['id']} a")
    page.wait_for_selector("#provenance-pair")
    assert "differs" in page.locator("#provenance-pair tr", has_text="precision").inner_text()
    assert page.locator("#array-diffs tbody tr").count() == len(arrays)
    images_decoded(page, "#figures img")
    page.screenshot(path=SHOTS / "audit_entry_precision.png", full_page=True)
    csv = page.request.get(f"{stack.url}/audit.csv?classification={entry['classification']}")
    assert csv.ok and f"\n{entry['id']}," in csv.text()
    student = signed_in(browser, stack, "alice")
    assert student.goto(f"{stack.url}/audit/{entry['id']}").status == 404


def test_postgresql_refuses_to_update_delete_or_truncate_an_entry(stack, source_runs):
    with Session(stack.engine) as session:  # an entry of its own to try it on, whatever other tests stored
        entry = AuditEntry(course_id=None, lesson="L03", case="N1", spec_key="k", spec={},
                           left_case_run_id=source_runs["N1"], left_variant="cpu/32/warm",
                           right_variant="cpu/64/warm", classification="not_compared", summary="test", figures=[])
        session.add(entry)
        session.commit()
        entry_id = entry.id
    for statement in (f"UPDATE audit_entries SET classification = 'identical' WHERE id = {entry_id}",
                      f"DELETE FROM audit_entries WHERE id = {entry_id}", "TRUNCATE audit_entries"):
        with Session(stack.engine) as session:
            with pytest.raises(DatabaseError, match="append-only"):
                session.execute(text(statement))
                session.commit()
    with Session(stack.engine) as session:
        assert session.get(AuditEntry, entry_id) is not None
