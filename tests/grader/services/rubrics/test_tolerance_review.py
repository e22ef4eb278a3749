"""The tolerance review page on the real app in-process (SQLite): a 32-bit and a 64-bit measurement of one case whose
difference exceeds a tolerance get an audit entry through the worker's own audit, and the page flags that tolerance
naming the entry; sign-offs are recorded with who and when without touching the version; a drafted version is
refused without a new rationale and published with one, through governance, on to the regrade preview."""

from __future__ import annotations

import dataclasses
import html
import re

import pytest

from tests.factories import mark_measured, reference_sheet

PAGE = "/courses/l03/rubrics/L03/2"
SHIFT_M = 0.0008  # lowers every centre height of the 64-bit twin: proxy and z differ by 0.8 mm (> 0.5 mm, > 0.1 mm)


def precision_twin(session, run, real, user) -> list:
    """A 64-bit audit re-run of `run` (measured as `real`) by `user`, whose stored measurement is `real` with every
    centre height SHIFT_M lower, compared by the worker's own audit (worker.audit.audit_finished_run): its entries."""
    from grader.core.audit import create_audit_rerun
    from rubric.metrics import case_metrics
    from worker.audit import audit_finished_run

    twin_run = create_audit_rerun(session, source=run, backend="cpu", precision="64", mode=None, user=user)
    spec = real.spec.model_copy(update={"precision": "64"})
    arrays = dict(real.arrays, z=real.arrays["z"] - SHIFT_M)
    twin = dataclasses.replace(real, spec=spec, arrays=arrays, metrics=case_metrics(spec, arrays), out_dir=None,
                               provenance=real.provenance.model_copy(update={"precision": "64"}))
    mark_measured(twin_run, twin)
    session.commit()
    return audit_finished_run(session, twin_run.id)


def _row(html: str, name: str) -> str:
    """A tolerance's row, without the <wbr> its names carry after their separators."""
    start = html.index(f'id="tol-{name}"')
    return html[start:html.index("</tr>", start)].replace("<wbr>", "")


def _version_row(version: str = "2"):
    from sqlalchemy import select

    from grader.core.db import new_session
    from grader.core.models import RubricVersion

    with new_session() as session:
        row = session.scalar(select(RubricVersion).where(RubricVersion.lesson == "L03",
                                                         RubricVersion.version == version))
        return None if row is None else (row.id, row.content_hash, row.content)


@pytest.fixture
def precision_pair(api, measured) -> int:
    """alice's N1 measured for real (32-bit), and an audit re-run at 64 bits whose stored measurement is the same run
    with every height 0.8 mm lower; the worker's audit compares them and stores the entry. Its id."""
    from sqlalchemy import select

    from grader.core.db import new_session
    from grader.core.models import CaseRun, User

    response = api.client.post("/v1/submissions", json={"sheet": reference_sheet() | {"student": "alice"}},
                               headers=api.as_("alice"))
    assert response.status_code == 202, response.text
    real = measured["N1"]
    with new_session() as session:
        run = session.scalar(select(CaseRun).where(CaseRun.submission_id == response.json()["id"],
                                                   CaseRun.name == "N1"))
        mark_measured(run, real)
        session.commit()
        entries = precision_twin(session, run, real, session.scalar(select(User).where(User.name == "tess")))
        assert [e.classification for e in entries] in (["numeric_drift"], ["relation_changed"]), entries
        assert (entries[0].left_variant, entries[0].right_variant) == ("cpu/32/warm", "cpu/64/warm")
        return entries[0].id


def test_the_review_flags_a_tolerance_narrower_than_a_measured_precision_difference(api, precision_pair):
    page = api.client.get(PAGE, headers=api.as_("prof"))
    assert page.status_code == 200, page.text
    proxy = _row(page.text, "proxy_resolution")
    assert "FLAGGED" in proxy and f'href="/audit/{precision_pair}"' in proxy
    assert f"audit entry {precision_pair} (N1, cpu/32/warm vs cpu/64/warm)" in proxy and "&gt; 0.0005 m" in proxy
    assert "FLAGGED" in _row(page.text, "n1_n4_max_dz")  # z itself differs by 0.8 mm > 0.1 mm
    vz = _row(page.text, "n1_n4_max_dvz")
    assert "FLAGGED" not in vz and "wider than the measured differences" in vz  # the shift left vz as it was
    assert "FLAGGED" not in _row(page.text, "stop_distance_resolution")  # no friction case compared
    # the stored measurements: N1's proxy over both variants, n = 2, spread the shift
    assert re.search(r"N1 · contact\.[a-z_]+: .*spread 0.0008, n = 2 · cpu/32/warm, cpu/64/warm", proxy, re.S), proxy
    assert "Instructor sign-off pending." in page.text
    # auditors read it; students and another course's instructor get the not-found page
    assert api.client.get(PAGE, headers=api.as_("tess")).status_code == 200
    for who in ("alice", "eve"):
        assert api.client.get(PAGE, headers=api.as_(who)).status_code == 404, who
    other = api.client.get(PAGE, headers=api.as_("eve"))
    assert "proxy_resolution" not in other.text
    assert api.client.get("/courses/l03/rubrics/L03/9", headers=api.as_("prof")).status_code == 404
    assert api.client.get("/courses/l03/rubrics/L3/2", headers=api.as_("prof")).status_code == 404


@pytest.fixture
def pg_api(tmp_path, monkeypatch):
    """The same app on a fresh PostgreSQL database (JSON nulls and partial indexes behave differently there)."""
    from tests import services
    from tests.grader.conftest import app_on

    with services.postgres_database() as url, app_on(url, tmp_path, monkeypatch) as state:
        yield state


def test_a_signoff_is_recorded_and_shown_and_never_changes_the_version(api):
    _signoff_flow(api)


def test_a_signoff_on_postgresql(pg_api):
    _signoff_flow(pg_api)


def _signoff_flow(api):
    from rubric.rubrics import parse_rubric

    assert "Instructor sign-off pending." in api.client.get(PAGE, headers=api.as_("prof")).text
    dashboard = api.client.get("/courses/l03/dashboard", headers=api.as_("prof")).text
    assert 'href="/courses/l03/rubrics/L03/2">L03 v2: new submissions are graded under it' in dashboard
    before = _version_row()
    signed = api.client.post(f"{PAGE}/signoff", data={"note": "checked against the audit log"},
                             headers=api.as_("prof"), follow_redirects=False)
    assert signed.status_code == 303 and signed.headers["location"].startswith(f"{PAGE}#signoff-")
    after = _version_row()
    assert after == before and parse_rubric(after[2]).content_hash == before[1]  # content and hash untouched
    page = api.client.get(PAGE, headers=api.as_("prof")).text
    assert "Instructor sign-off pending." not in page
    assert "sign-off pending" not in page.lower()  # one status: the shipped record's own note is dropped too
    assert "rubric v2 author (measured-items revision), " in page
    dashboard = api.client.get("/courses/l03/dashboard", headers=api.as_("prof")).text
    assert "Rubric sign-offs pending (0)" in dashboard and "L03 v2: new submissions" not in dashboard
    assert re.search(r"by prof, \d{4}-\d\d-\d\d \d\d:\d\d UTC: checked against the audit log", page)
    listed = api.client.get("/courses/l03/rubrics", headers=api.as_("prof")).text
    assert re.search(r'id="signoff-2"><div>signed off by prof', listed)
    assert re.search(r'id="signoff-1"><span class="verdict verdict-pending">not signed off yet', listed)
    assert f'href="{PAGE}"' in listed
    # twice by the same instructor: refused, named; an auditor, a student, another site: refused, nothing stored
    again = api.client.post(f"{PAGE}/signoff", data={"note": ""}, headers=api.as_("prof"))
    assert again.status_code == 409 and "prof already signed L03 v2 off" in again.text
    assert api.client.post(f"{PAGE}/signoff", data={}, headers=api.as_("tess")).status_code == 404
    assert api.client.post(f"{PAGE}/signoff", data={}, headers=api.as_("alice")).status_code == 404
    cross = api.client.post(f"{PAGE}/signoff", data={}, headers=api.as_("prof") | {"Origin": "https://evil.example"})
    assert cross.status_code == 403
    long = api.client.post("/courses/l03/rubrics/L03/1/signoff", data={"note": "x" * 2001}, headers=api.as_("prof"))
    assert long.status_code == 422 and "<code>note</code>: at most 2000 characters" in long.text
    # another course sees the shipped version still pending: a sign-off is the course's own
    assert "Instructor sign-off pending." in api.client.get("/courses/other/rubrics/L03/2", headers=api.as_("eve")).text
    from sqlalchemy import func, select

    from grader.core.db import new_session
    from grader.core.models import RubricSignoff

    with new_session() as session:
        assert session.scalar(select(func.count()).select_from(RubricSignoff)) == 1


def _draft_form(api, **changes) -> dict:
    page = api.client.get(f"{PAGE}/draft", headers=api.as_("prof"))
    assert page.status_code == 200
    form = {"version": re.search(r'name="version" class="short" value="([^"]*)"', page.text).group(1),
            "notes": "tightened after the tolerance review"}
    for name, value in re.findall(r'name="value\.([a-z0-9_]+)" class="short" value="([^"]*)"', page.text):
        form[f"value.{name}"] = value
    for name, text in re.findall(r'name="rationale\.([a-z0-9_]+)" rows="3">([^<]*)</textarea>', page.text, re.S):
        form[f"rationale.{name}"] = html.unescape(text)  # what a browser sends back
    return form | changes


def test_a_drafted_version_needs_a_new_rationale_for_each_changed_tolerance_then_publishes(api):
    form = _draft_form(api)
    assert form["version"] == "3" and form["value.proxy_resolution"] == "0.0005" and len(form) == 2 + 2 * 11
    unchanged = api.client.post(f"{PAGE}/draft", data=form, headers=api.as_("prof"))
    assert unchanged.status_code == 422 and "no tolerance differs from v2" in unchanged.text
    no_reason = api.client.post(f"{PAGE}/draft", data=form | {"value.proxy_resolution": "0.001"},
                                headers=api.as_("prof"))
    assert no_reason.status_code == 422
    assert ("<code>tolerances.proxy_resolution.rationale</code>: changed 0.0005 -&gt; 0.001 m (items A2, X2, X3): "
            "a changed tolerance needs a new rationale") in no_reason.text
    assert 'id="error-proxy_resolution-rationale"' in no_reason.text and 'value="0.001"' in no_reason.text
    bad = api.client.post(f"{PAGE}/draft", data=form | {"value.n1_n4_max_dz": "-1", "version": "x"},
                          headers=api.as_("prof"))
    assert bad.status_code == 422 and "tolerances.n1_n4_max_dz.value" in bad.text and "<code>version</code>" in bad.text
    assert _version_row("3") is None  # nothing half-stored
    assert api.client.post(f"{PAGE}/draft", data=form, headers=api.as_("tess")).status_code == 404
    assert api.client.get(f"{PAGE}/draft", headers=api.as_("tess")).status_code == 404

    reason = "reviewed against the measured precision spread: 1 mm keeps a proxy direction stable across precisions"
    published = api.client.post(f"{PAGE}/draft", data=form | {"value.proxy_resolution": "0.001",
                                                                "rationale.proxy_resolution": reason},
                                headers=api.as_("prof"), follow_redirects=False)
    assert published.status_code == 303 and published.headers["location"] == "/courses/l03/regrade?version=3&lesson=L03"
    _, _, content = _version_row("3")
    tol = content["tolerances"]["proxy_resolution"]
    assert (tol["value"], tol["rationale"], tol["reviewer"]) == (0.001, reason, "prof")
    assert content["review"]["reviewer"] == "prof" and "changed: proxy_resolution" in content["review"]["notes"]
    assert content["tolerances"]["n1_n4_max_dz"] == _version_row("2")[2]["tolerances"]["n1_n4_max_dz"]
    preview = api.client.get(published.headers["location"], headers=api.as_("prof"))
    assert preview.status_code == 200 and "tolerances.proxy_resolution: 0.0005 m -&gt; 0.001 m" in preview.text
    # the same version string again with other content: governance refuses it (a published version never changes)
    clash = api.client.post(f"{PAGE}/draft", data=form | {"value.proxy_resolution": "0.002",
                                                            "rationale.proxy_resolution": reason + " again"},
                            headers=api.as_("prof"))
    assert clash.status_code == 409 and "published and immutable" in clash.text


@pytest.mark.parametrize("reviewer, signed", [
    ("rubric v2 author (measured-items revision; instructor sign-off pending)", "rubric v2 author (measured-items revision)"),
    ("variant space author (instructor sign-off pending)", "variant space author"),
    ("ivan", "ivan"),
])
def test_a_review_record_drops_its_pending_note_once_signed_off(reviewer, signed):
    from grader.services.rubrics.tolerance_review import review_record

    assert review_record(reviewer, signed_off=False) == reviewer
    assert review_record(reviewer, signed_off=True) == signed
