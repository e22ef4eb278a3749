"""Every class of hostile input gets a 4xx naming the field and the rule, and nothing is stored (issue 12, part 4).

One table of bodies, one of paths, then tokens, other people's objects, the rate limit and the OpenAPI's promises.
"""

from __future__ import annotations

import json

import pytest
from sqlalchemy import func, select

from tests.factories import reference_sheet


def stored() -> dict[str, int]:
    from grader.core.db import new_session
    from grader.core.models import CaseRun, Event, Submission

    with new_session() as session:
        return {m.__tablename__: session.scalar(select(func.count()).select_from(m)) for m in (Submission, CaseRun, Event)}


NOTHING = {"submissions": 0, "case_runs": 0, "events": 0}


def nested(depth: int) -> object:
    value: object = 0
    for _ in range(depth):
        value = [value]
    return value


def sheet_with(path: str, value) -> str:
    """The reference sheet as JSON text with the item at dotted `path` replaced by `value` (raw JSON text)."""
    sheet = reference_sheet()
    *parents, last = path.split(".")
    node = sheet
    for key in parents:
        node = node[int(key)] if isinstance(node, list) else node[key]
    marker = "__REPLACED__"
    node[last] = marker
    return json.dumps({"sheet": sheet}).replace(f'"{marker}"', value)


def big_sheet_explanation(size: int) -> str:
    return sheet_with("answers.A5.explanation", json.dumps("x" * size))


JSON = "application/json"
# (case id, body bytes, content type, expected status, field the first error must name, words in its rule)
BODIES = [
    ("invalid-utf8", b'{"sheet": "\xff\xfe"}', JSON, 422, "body", "UTF-8"),
    ("utf16-json", json.dumps({"sheet": {}}).encode("utf-16"), JSON, 422, "body", "UTF-8"),
    ("not-json", b"sheet=1", JSON, 422, "body", "valid JSON"),
    ("truncated-json", b'{"sheet": {"lesson": "L03"', JSON, 422, "body", "valid JSON"),
    ("form-not-json", b"sheet=1", "application/x-www-form-urlencoded", 422, "body", "valid dictionary"),
    ("no-content-type", json.dumps({"sheet": reference_sheet()}).encode(), None, 422, "body", "valid dictionary"),
    ("nan", sheet_with("answers.C5.pair_friction", "NaN").encode(), JSON, 422, "sheet.answers.C5.pair_friction",
     "finite"),
    ("infinity", sheet_with("answers.C5.pair_friction", "Infinity").encode(), JSON, 422,
     "sheet.answers.C5.pair_friction", "finite"),
    ("overflow-to-inf", sheet_with("configs.extension.dt", "1e400").encode(), JSON, 422,
     "sheet.configs.extension.dt", "finite"),
    ("nested-40", json.dumps({"sheet": {"deep": nested(40)}}).encode(), JSON, 422, "sheet.deep.0.0", "32 levels"),
    ("nested-496", json.dumps({"sheet": {"deep": nested(496)}}).encode(), JSON, 422, "sheet.deep.0.0", "32 levels"),
    ("nested-100000", b"[" * 100_000 + b"]" * 100_000, JSON, 422, "body", "32 levels"),
    ("integer-5000-digits", sheet_with("answers.C1.samples", "9" * 5000).encode(), JSON, 422, "sheet.answers.C1.samples",
     "at most 4300 digits, this one has 5000"),  # past Python's digit limit: named by its field (issue 44, 6a)
    ("integer-absurd", sheet_with("answers.C1.samples", "9" * 300).encode(), JSON, 422, "sheet.answers.C1.samples",
     "less than or equal"),
    ("list-absurd", sheet_with("answers.A1.samples_150", json.dumps(["N1"] * 50_000)).encode(), JSON, 422,
     "sheet.answers.A1.samples_150", "at most 16 items"),  # the sheet's caps, before any work (grader.services.submissions.sheets)
    ("string-absurd", big_sheet_explanation(500_000).encode(), JSON, 422, "sheet.answers.A5.explanation", "at most 4000"),
    ("substeps-absurd", sheet_with("configs.extension.substeps", "1000000000").encode(), JSON, 422,
     "sheet.configs.extension.substeps", "less than or equal"),
    ("unknown-top-field", json.dumps({"sheet": reference_sheet(), "priority": "high"}).encode(), JSON, 422,
     "priority", "Extra inputs"),
    ("unknown-sheet-field", sheet_with("answers.A3.confidence", "0.9").encode(), JSON, 422,
     "sheet.answers.A3.confidence", "Extra inputs"),
    ("oversized-declared", big_sheet_explanation(1_100_000).encode(), JSON, 413, "body", "at most"),
]


@pytest.mark.parametrize("body, content_type, status, field, rule",
                         [case[1:] for case in BODIES], ids=[case[0] for case in BODIES])
def test_a_hostile_submission_body_is_refused_naming_field_and_rule_and_nothing_is_stored(
        api, body, content_type, status, field, rule):
    headers = api.as_("alice") | ({"content-type": content_type} if content_type else {})
    response = api.client.post("/v1/submissions", content=body, headers=headers)
    assert response.status_code == status, response.text[:500]
    errors = response.json()["errors"]
    assert response.json()["detail"] and errors, response.text[:500]
    assert errors[0]["field"].startswith(field) and rule in errors[0]["rule"], errors[:3]
    assert len(response.content) < 20_000  # an absurd input never makes an absurd answer
    assert stored() == NOTHING and api.sent == []


def test_an_oversized_body_sent_in_chunks_without_a_length_is_refused(api):
    from grader.core.settings import settings

    body = big_sheet_explanation(settings.max_body_bytes).encode()

    def chunks():
        for start in range(0, len(body), 64_000):
            yield body[start:start + 64_000]

    response = api.client.post("/v1/submissions", content=chunks(),
                               headers=api.as_("alice") | {"content-type": JSON})
    assert "content-length" not in response.request.headers  # really streamed
    assert response.status_code == 413 and response.json()["errors"][0]["field"] == "body"
    assert stored() == NOTHING


def test_an_oversized_non_json_body_streamed_without_a_length_is_refused(api):
    from grader.core.settings import settings

    def chunks():
        for _ in range(settings.max_body_bytes // 50_000 + 2):
            yield b"x" * 50_000

    response = api.client.post("/v1/submissions", content=chunks(),
                               headers=api.as_("alice") | {"content-type": "text/plain"})
    assert response.status_code == 413 and response.json()["errors"][0]["field"] == "body"
    assert stored() == NOTHING


def test_many_errors_are_cut_to_the_first_twenty_and_say_so(api):
    empty = {"lesson": "L03", "student": "alice", "answers": {}, "configs": {}}  # 26 answers and 2 configs missing
    response = api.client.post("/v1/submissions", json={"sheet": empty}, headers=api.as_("alice"))
    assert response.status_code == 422
    assert len(response.json()["errors"]) == 20 and "the first 20 of 28 errors" in response.json()["detail"]
    assert stored() == NOTHING


@pytest.mark.parametrize("route", ["/v1/rubrics/versions", "/v1/courses/l03/regrades"])
def test_the_body_guard_covers_every_json_route(api, route):
    response = api.client.post(route, content=json.dumps({"version": nested(200)}),
                               headers=api.as_("prof") | {"content-type": JSON})
    assert response.status_code == 422 and "32 levels" in response.json()["errors"][0]["rule"], response.text


ID_ROUTES = ["", "/grade", "/grades", "/case-runs", "/events", "/series",
             "/case-runs/N1/files/spec.json", "/gradescope.json"]


@pytest.mark.parametrize("sid", ["9223372036854775808", str(2**31), "0", "-1", "1e3", "99999999999999999999999999"])
@pytest.mark.parametrize("route", ID_ROUTES)
def test_an_id_outside_the_database_range_is_a_422_naming_the_parameter(api, sid, route):
    response = api.client.get(f"/v1/submissions/{sid}{route}", headers=api.as_("prof"))
    assert response.status_code == 422, response.text
    assert response.json()["errors"][0]["field"] == "path.submission_id"


@pytest.mark.parametrize("path", ["/v1/audit/entries/9223372036854775808",
                                  "/v1/case-runs/9223372036854775808/audit-reruns"])
def test_audit_ids_follow_the_same_rule(api, path):
    call = api.client.post if path.endswith("reruns") else api.client.get
    response = call(path, headers=api.as_("tess"), **({"json": {}} if path.endswith("reruns") else {}))
    assert response.status_code == 422 and response.json()["errors"][0]["field"].startswith("path.")


@pytest.fixture
def alices(api):
    response = api.client.post("/v1/submissions", json={"sheet": reference_sheet()}, headers=api.as_("alice"))
    assert response.status_code == 202, response.text
    return response.json()["id"]


TRAVERSALS = ["..%2F..%2F..%2Fetc%2Fpasswd", "%2E%2E", "%2E%2E%2Fsecret.png", "..%5C..%5Cgrader.db", "a%00.png", "%2Fetc%2Fpasswd",
              ".hidden.png", "x" * 300 + ".png"]


@pytest.mark.parametrize("name", TRAVERSALS)
@pytest.mark.parametrize("template", ["/v1/submissions/{sid}/case-runs/N1/files/{name}",
                                      "/v1/submissions/{sid}/case-runs/{name}/files/spec.json"])
def test_path_traversal_never_reaches_the_filesystem(api, alices, template, name):
    from grader.core.db import new_session
    from grader.core.models import CaseRun
    from grader.core.settings import settings

    secret = settings.artifacts_dir / "secret.png"  # what a traversal would try to read
    secret.parent.mkdir(parents=True, exist_ok=True)
    secret.write_bytes(b"\x89PNG secret")
    with new_session() as session:  # a run with an artifact folder, so a lookup could reach the disk
        for run in session.scalars(select(CaseRun)):
            run.artifact_dir = str(settings.artifacts_dir / "runs" / run.name)
        session.commit()
    response = api.client.get(template.format(sid=alices, name=name), headers=api.as_("alice"))
    assert response.status_code in (404, 422), response.text
    assert b"secret" not in response.content
    assert response.headers["content-type"].startswith("application/json")
    if response.status_code == 422:
        assert response.json()["errors"][0]["field"] in ("path.filename", "path.name")


@pytest.mark.parametrize("headers", [
    {}, {"Authorization": ""}, {"Authorization": "Bearer"}, {"Authorization": "Bearer "},
    {"Authorization": "Token abc"}, {"Authorization": "Bearer not-a-token"}, {"Authorization": "Bearer " + "x" * 8000},
    {"Authorization": "Bearer l03_\u00e9\u00ff".encode("latin-1")}, {"Authorization": "Basic eDp5"},
])
def test_missing_and_malformed_tokens_get_401_and_store_nothing(api, headers):
    response = api.client.post("/v1/submissions", json={"sheet": reference_sheet()}, headers=headers)
    assert response.status_code == 401, response.text
    assert response.json()["detail"] and response.headers["www-authenticate"] == "Bearer"
    assert stored() == NOTHING


def test_another_students_or_courses_objects_are_not_found(api, alices):
    from grader.core.db import new_session
    from grader.core.models import CaseRun

    with new_session() as session:
        run_id = session.scalars(select(CaseRun.id)).first()
    for route in ID_ROUTES:
        for who in ("bob", "eve"):  # another student of the course; an instructor of another course
            response = api.client.get(f"/v1/submissions/{alices}{route}", headers=api.as_(who))
            assert response.status_code == 404, (route, who, response.text)
    assert api.client.get("/v1/courses/l03/dashboard", headers=api.as_("eve")).status_code == 404
    assert api.client.get("/v1/courses/l03/grades.csv", headers=api.as_("eve")).status_code == 404
    before = stored()
    response = api.client.post(f"/v1/case-runs/{run_id}/audit-reruns", json={}, headers=api.as_("eve"))
    assert response.status_code == 404 and stored() == before


def test_submissions_are_rate_limited_per_person_with_retry_after(api, monkeypatch):
    from grader.core.settings import settings

    monkeypatch.setattr(settings, "rate_limit_submissions", "3/minute")
    codes = [api.client.post("/v1/submissions", json={"sheet": reference_sheet()}, headers=api.as_("alice")).status_code
             for _ in range(3)]
    assert codes == [202, 202, 202]
    refused = api.client.post("/v1/submissions", json={"sheet": reference_sheet()}, headers=api.as_("alice"))
    assert refused.status_code == 429, refused.text
    assert 1 <= int(refused.headers["retry-after"]) <= 60
    assert refused.json()["errors"][0] == {"field": "submissions",
                                           "rule": "at most 3 per 1 minute submissions per person"}
    assert stored()["submissions"] == 3
    # Bad sheets count too (each costs validation: the service counts before any work); another person has their own
    # allowance (the sheet form's submissions count in the same one: tests/grader/services/identity/test_limits_every_door.py).
    assert api.client.post("/v1/submissions", json={"sheet": {}}, headers=api.as_("alice")).status_code == 429
    assert api.client.post("/v1/submissions", json={"sheet": reference_sheet()}, headers=api.as_("prof")).status_code == 202


def test_timestamps_are_utc_with_an_offset(api, alices):
    from datetime import datetime, timedelta

    body = api.client.get(f"/v1/submissions/{alices}", headers=api.as_("alice")).json()
    events = api.client.get(f"/v1/submissions/{alices}/events", headers=api.as_("alice")).json()
    runs = api.client.get(f"/v1/submissions/{alices}/case-runs", headers=api.as_("alice")).json()
    dashboard = api.client.get("/v1/courses/l03/dashboard", headers=api.as_("prof")).json()
    versions = api.client.get("/v1/rubrics/L03/versions", headers=api.as_("prof")).json()
    stamps = [body["created_at"], body["updated_at"], *(e["at"] for e in events), runs[0]["queued_at"],
              *(r["submitted_at"] for r in dashboard["roster"]), *(v["published_at"] for v in versions)]
    for stamp in stamps:
        parsed = datetime.fromisoformat(stamp)
        assert parsed.utcoffset() == timedelta(0), stamp


def test_openapi_documents_every_error_status_as_error_body(api):
    spec = api.client.get("/openapi.json").json()
    assert "HTTPValidationError" not in json.dumps(spec)  # FastAPI's own 422 shape is never answered
    # No bearer token is asked of the health check, nor of a sign-in link's exchange (its secret is its credential)
    public = {"/v1/health", "/v1/sign-in-links/{secret}/token"}
    for path, operations in spec["paths"].items():
        for method, operation in operations.items():
            codes = set(operation["responses"])
            if path not in public:
                assert "401" in codes, (method, path)
            if "{" in path:
                assert "422" in codes, (method, path)
            for code, response in operation["responses"].items():
                if code.startswith(("4", "5")):
                    assert list(response["content"]) == ["application/json"], (method, path, code)
                    assert response["content"]["application/json"]["schema"]["$ref"].endswith("/ErrorBody")
    post = spec["paths"]["/v1/submissions"]["post"]["responses"]
    assert {"401", "403", "413", "422", "429"} <= set(post) and "Retry-After" in post["429"]["headers"]
    assert list(spec["paths"]["/v1/courses/{course}/grades.csv"]["get"]["responses"]["200"]["content"]) == ["text/csv"]
    ids = spec["paths"]["/v1/submissions/{submission_id}"]["get"]["parameters"][0]["schema"]
    assert (ids["minimum"], ids["maximum"]) == (1, 2**31 - 1)


def test_a_405_lists_every_method_of_the_path(api):
    response = api.client.request("DELETE", "/v1/submissions", headers=api.as_("alice"))
    assert response.status_code == 405 and response.headers["allow"] == "GET, POST"


def test_pages_answer_ids_outside_the_range_without_a_500(api):
    for path in (f"/submissions/{2**63}", f"/audit/{2**63}", f"/submissions/{2**63}/series.json", f"/audit/{2**31}"):
        assert api.client.get(path, headers=api.as_("prof")).status_code == 404, path
    refused = api.client.post("/audit/reruns", data={"case_run_id": str(2**63)}, headers=api.as_("tess"),
                              follow_redirects=False)
    assert refused.status_code == 422 and refused.json()["errors"][0]["field"] == "case_run_id", refused.text


def test_the_audit_csv_writes_utc_with_an_offset():
    from datetime import datetime
    from types import SimpleNamespace

    from grader.services.reports.audit import entries_csv

    entry = SimpleNamespace(id=1, created_at=datetime(2026, 1, 2, 3, 4, 5), lesson="L03", case="N1",  # not a clock time: CSV format
                            left_case_run_id=1, right_case_run_id=2, left_variant="cpu/32/warm",
                            right_variant="cpu/64/warm", left_provenance=None, right_provenance=None,
                            classification="identical", summary="")
    assert entries_csv([entry]).splitlines()[1].startswith("1,2026-01-02T03:04:05+00:00,")  # not a clock time: format


def test_a_repeated_query_parameter_is_refused_naming_it(api):
    response = api.client.get("/v1/audit/entries?case=N1&case=N2", headers=api.as_("tess"))
    assert response.status_code == 422
    assert response.json()["errors"] == [{"field": "query.case", "rule": "given more than once; give one value"}]
    once = api.client.get("/v1/audit/entries?case=N1", headers=api.as_("tess"))
    assert once.status_code == 200
