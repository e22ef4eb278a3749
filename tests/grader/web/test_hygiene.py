"""Hygiene of what the service sends (issue 26): CSV cells a spreadsheet would run are neutralised, every answer
carries the security headers and pages and grades are never cached, and the API docs load nothing from elsewhere."""

from __future__ import annotations

import csv
import io
import re

import pytest
from sqlalchemy.orm import Session

from tests.factories import ROOT, reference_sheet

# Student ids the roster import accepts (letters, digits, _.@-) that a spreadsheet would evaluate.
FORMULA_IDS = ("-2-3", "@A1")


def _roster_students(api) -> dict[str, dict[str, str]]:
    text = "student_id,name,email\n" + "".join(f"{sid},Someone,s{n}@example.edu\n" for n, sid in enumerate(FORMULA_IDS))
    imported = api.client.post("/v1/courses/l03/roster", json={"csv": text}, headers=api.as_("prof"))
    assert imported.status_code == 200, imported.text
    return {e["student"]: {"Authorization": f"Bearer {e['token']}"} for e in imported.json()}


def test_course_grade_exports_neutralise_ids_a_spreadsheet_would_evaluate(api):
    from grader.core import db
    from grader.core.models import Grade, Submission

    students = _roster_students(api)
    for student, headers in students.items():
        created = api.client.post("/v1/submissions", json={"sheet": reference_sheet() | {"student": student}},
                                  headers=headers)
        assert created.status_code == 202, created.text
        report = {"lesson": "L03", "student": student, "rubric_version": "2", "rubric_hash": "x",
                  "engine_version": "1.3.3", "total": 1, "max_total": 2, "complete": True, "items": [],
                  "config_findings": []}
        with Session(db.get_engine()) as session:
            session.add(Grade(submission_id=created.json()["id"], rubric_lesson="L03", rubric_version="2",
                              rubric_hash="x", total=1, max_total=2, report=report))
            session.get(Submission, created.json()["id"]).status = "graded"
            session.commit()
    exported = api.client.get("/v1/courses/l03/grades.csv", headers=api.as_("prof"))
    assert exported.status_code == 200, exported.text
    assert [r["student"] for r in csv.DictReader(io.StringIO(exported.text))] == ["'-2-3", "'@A1"]
    api.client.post("/sign-in", data={"token": api.tokens["prof"], "next": "/submissions"})
    page = api.client.get("/courses/l03/grades.csv")
    assert page.status_code == 200 and page.text == exported.text  # the pages serve the same bytes


def test_the_audit_csv_neutralises_a_summary_a_spreadsheet_would_evaluate():
    from datetime import datetime
    from types import SimpleNamespace

    from grader.services.reports.audit import entries_csv

    entry = SimpleNamespace(id=1, created_at=datetime(2026, 1, 2, 3, 4, 5), lesson="L03", case="N1",  # not a clock time: CSV format
                            left_case_run_id=1, right_case_run_id=2, left_variant="cpu/32/warm",
                            right_variant="cpu/64/warm", left_provenance={"versions": {"genesis": "@latest"}},
                            right_provenance=None, classification="identical", summary="=HYPERLINK(\"x\")")
    (row,) = csv.DictReader(io.StringIO(entries_csv([entry])))
    assert row["summary"] == "'=HYPERLINK(\"x\")" and row["left_genesis"] == "'@latest"


@pytest.mark.parametrize(("cell", "written"), [
    ("=1+1", "'=1+1"), ("+1+1", "'+1+1"), ("-2-3", "'-2-3"), ("@SUM(A1)", "'@SUM(A1)"), ("\t=1", "'\t=1"),
    ("\r=1", "'\r=1"), ("alice", "alice"), ("a=1", "a=1"), ("", ""),
    # numbers stay numbers: a penalty, a signed score
    ("-5", "-5"), ("-0.25", "-0.25"), ("+3", "+3"), ("-1e-3", "-1e-3"), (-5, -5), (None, None)])
def test_cells_a_spreadsheet_would_evaluate_get_a_leading_quote(cell, written):
    from rubric.exports import spreadsheet_safe

    assert spreadsheet_safe(cell) == written


def test_every_csv_export_is_written_by_the_one_safe_writer():
    writers = [p for p in [*(ROOT / "grader").rglob("*.py"), *(ROOT / "rubric").rglob("*.py")]
               if re.search(r"csv\.(writer|DictWriter)\(", p.read_text()) and p != ROOT / "rubric" / "exports.py"]
    assert writers == [], "write CSV through rubric.exports.csv_text, which neutralises formulas"


# --- security headers -------------------------------------------------------------------------------------------

SECURITY = {"x-content-type-options": "nosniff", "referrer-policy": "same-origin", "x-frame-options": "DENY"}


def _assert_secure(response, *, cached: bool = False) -> None:
    for name, value in SECURITY.items():
        assert response.headers.get(name) == value, (response.request.url, name)
    policy = response.headers["content-security-policy"]
    assert "default-src 'self'" in policy and "frame-ancestors 'none'" in policy
    assert "unsafe-inline" not in policy and "unsafe-eval" not in policy
    if not cached:
        assert response.headers.get("cache-control") == "private, no-store", response.request.url


def test_pages_exports_and_grades_carry_the_security_headers_and_are_never_cached(api):
    sid = api.client.post("/v1/submissions", json={"sheet": reference_sheet()}, headers=api.as_("alice")).json()["id"]
    for path in (f"/v1/submissions/{sid}", f"/v1/submissions/{sid}/grade", f"/v1/submissions/{sid}/events",
                 "/v1/courses/l03/grades.csv", "/v1/health", "/v1/nothing-here"):
        _assert_secure(api.client.get(path, headers=api.as_("prof")))
    _assert_secure(api.client.get("/sign-in"))
    api.client.post("/sign-in", data={"token": api.tokens["prof"], "next": "/submissions"})
    for path in ("/submissions", f"/submissions/{sid}", "/courses/l03/dashboard", "/courses/l03/grades.csv",
                 "/audit.csv", "/no-such-page"):
        response = api.client.get(path)
        assert response.status_code in (200, 404), (path, response.status_code)
        _assert_secure(response)
    static = api.client.get("/static/style.css")
    _assert_secure(static, cached=True)
    assert "no-store" not in static.headers.get("cache-control", "")  # assets may be cached


def test_pages_need_no_inline_script_or_style_attribute():
    """The policy forbids inline script and style attributes, so no template may rely on one."""
    templates = sorted((ROOT / "grader" / "templates").rglob("*.html"))
    assert len(templates) > 30  # every context's folder, not only the shared pages at the top
    for template in templates:
        text = template.read_text()
        assert not re.search(r"<script(?![^>]*\bsrc=)", text), template.name
        assert not re.search(r"\sstyle=|\son[a-z]+=", text), template.name


# --- API docs -----------------------------------------------------------------------------------------------------


def test_the_api_docs_load_every_asset_from_the_app(api):
    docs = api.client.get("/docs")
    assert docs.status_code == 200
    assets = re.findall(r"""(?:src|href)=["']([^"']+)""", docs.text) + re.findall(r"url:\s*'([^']+)'", docs.text)
    assert assets and not [a for a in assets if re.match(r"(https?:)?//", a)], assets
    assert "http://" not in docs.text and "https://" not in docs.text
    for asset in assets:
        assert api.client.get(asset).status_code == 200, asset
    # Swagger UI's one inline start-up script runs by its hash; no other inline script may.
    policy = docs.headers["content-security-policy"]
    assert re.search(r"script-src 'self' 'sha256-[A-Za-z0-9+/=]+';", policy) and "frame-ancestors 'none'" in policy
    assert api.client.get("/redoc").status_code == 404


def test_the_vendored_docs_assets_are_recorded_small_and_packaged():
    static = ROOT / "grader" / "static"
    vendored = ("swagger-ui-bundle.js", "swagger-ui.css", "swagger-favicon.png")
    assert sum((static / name).stat().st_size for name in vendored) < 2_100_000
    record = (static / "VENDORED.md").read_text()
    assert all(name in record for name in vendored) and "Apache-2.0" in record
    assert re.search(r"swagger-ui-dist \d+\.\d+\.\d+", record)
    package_data = (ROOT / "pyproject.toml").read_text()
    assert '"static/*"' in package_data
