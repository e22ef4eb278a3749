"""No 5xx from any page form (issue 31, item 4): every POST page route, with the fields its pages' forms name, is sent
a fixed generated list of bad posts (every field huge, every field a file part, text with CR-only line endings and
colliding YAML keys, a roster or YAML file with a field past the csv module's limit, nothing at all) as a student and
as an instructor; each answer is below 500 and carries the security headers. A fixed list, not a search: it runs in
seconds and fails the same way every time."""

from __future__ import annotations

import re
from html.parser import HTMLParser

import pytest
from fastapi.routing import iter_route_contexts
from fastapi.testclient import TestClient

from grader.main import app
from grader.core.settings import settings
from tests.factories import reference_sheet
from tests.grader.services.setup.test_assignments import create

ODD_TEXT = "a: 1\r'a.b': 2\rstudent_id,name,email\rs1,\x00x,y@z.io\r\u202e\ufeff"
COLLIDING_YAML = b"lesson: L03\nstudent: alice\nanswers: {}\nconfigs:\n  table_exercise: {a: 1, 'a.b': 2}\n"
HUGE_CSV = b"student_id,name,email\rs1," + b"x" * 140_000 + b",a@b.io\r"
GENERIC = ("action", "token", "next", "file", "csv", "comment", "score", "message", "item_id", "answer", "timezone",
           "student", "links", "title", "backend", "reason")


class _Forms(HTMLParser):
    """Each post form's action and the names of its fields."""

    def __init__(self):
        super().__init__()
        self.forms: list[tuple[str, set[str]]] = []

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        if tag == "form" and (a.get("method") or "get").lower() == "post":
            self.forms.append((a.get("action") or "", set()))
        elif tag in ("input", "select", "textarea", "button") and a.get("name") and self.forms:
            self.forms[-1][1].add(a["name"])


def _fill(path: str, values: dict[str, str]) -> str:
    return re.sub(r"\{(\w+)(?::\w+)?\}", lambda m: values.get(m.group(1), "1"), path)


def _routes(method: str) -> list[str]:
    return sorted({r.path for r in iter_route_contexts(app.routes)
                   if method in (getattr(r, "methods", None) or ()) and not r.path.startswith(("/v1", "/static"))
                   and r.path not in ("/docs", "/openapi.json", "/metrics")})


def _variants(names: list[str]) -> list[tuple[str, dict, dict]]:
    """(name, data, files) of each bad post; each fits the body limit, so it reaches the route (413 is the guard's)."""
    each = max(1, min(200_000, (settings.max_body_bytes - 50_000) // max(1, len(names))))
    return [
        ("nothing", {}, {}),
        ("huge", {n: "x" * each for n in names}, {}),
        ("odd text", {n: ODD_TEXT for n in names}, {}),
        ("file parts", {}, {n: (f"{n}.yaml", COLLIDING_YAML, "application/yaml") for n in names}),
        ("odd files", {n: "1" for n in names if n not in ("file", "csv")},
         {"file": ("sheet.yaml", COLLIDING_YAML, "application/yaml"), "csv": ("r.csv", HUGE_CSV, "text/csv")}),
    ]


@pytest.fixture
def ids(api) -> dict[str, str]:
    aid = create(api).json()["id"]
    sid = api.client.post("/v1/submissions", json={"sheet": reference_sheet()}, headers=api.as_("alice")).json()["id"]
    run = api.client.get(f"/v1/submissions/{sid}/case-runs", headers=api.as_("alice")).json()[0]["id"]
    return {"course": "l03", "assignment_id": str(aid), "submission_id": str(sid), "lesson": "L03", "version": "1",
            "request_id": "1", "case_run_id": str(run), "student": "alice", "secret": "A" * 43, "name": "x"}


def test_no_page_form_answers_5xx_to_bad_input(api, ids, monkeypatch):
    monkeypatch.setattr(settings, "rate_limit_submissions", "100000/minute")
    monkeypatch.setattr(settings, "rate_limit_draft_saves", "100000/minute")
    monkeypatch.setattr(settings, "rate_limit_sign_in_failures", "100000/minute")
    monkeypatch.setattr(settings, "rate_limit_link_guesses", "100000/minute")
    client = TestClient(app, raise_server_exceptions=False)
    names: dict[str, set[str]] = {}
    for path in _routes("GET"):  # the forms the pages show, with the names they post
        for who in ("alice", "prof"):
            page = client.get(_fill(path, ids), headers=api.as_(who))
            if page.headers.get("content-type", "").startswith("text/html"):
                parser = _Forms()
                parser.feed(page.text)
                for action, fields in parser.forms:
                    names.setdefault(action.split("?")[0], set()).update(fields)
    posts = _routes("POST")
    assert len(posts) >= 20 and len(names) >= 10, (posts, names)
    failures = []
    for path in posts:
        target = _fill(path, ids)
        fields = sorted(names.get(target, set()) | set(GENERIC))
        for variant, data, files in _variants(fields):
            for who in ("alice", "prof"):
                answer = client.post(target, data=data, files=files or None, headers=api.as_(who),
                                     follow_redirects=False)
                if answer.status_code >= 500 or answer.headers.get("X-Content-Type-Options") != "nosniff":
                    failures.append((path, variant, who, answer.status_code, answer.text[:200]))
    assert failures == [], failures
