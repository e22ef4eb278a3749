"""Conditional reads of a complete report (grader.web.etag) over the real app in-process (SQLite): 304 to a browser
that holds the same answer, a new ETag whenever what the reader may see changes (a release, a regrade, the page's
language), none while a report is not complete, and a cached body never served to another reader. Grades are real:
checkpoint sheets graded on the lesson's cases as really measured (the session's Genesis runs)."""

from __future__ import annotations

import pytest

from tests.factories import rubric_v3
from tests.grader.services.setup.test_assignments import create, submit
from tests.grader.services.setup.test_assignments import lesson_cases_stored  # noqa: F401 - autouse: the lesson measured

# Every answer about a complete report that carries an ETag.
READS = ("/submissions/{sid}", "/submissions/{sid}/results.json", "/v1/submissions/{sid}",
         "/v1/submissions/{sid}/grade")


@pytest.fixture(autouse=True)
def fresh_cache():
    from grader.web.etag import BODIES

    BODIES.clear()  # ids repeat across the tests' databases
    yield
    BODIES.clear()


def graded(api, **assignment) -> tuple[int, int]:
    aid = create(api, **assignment).json()["id"]
    response = submit(api, aid)
    assert response.status_code == 202 and response.json()["status"] == "graded", response.text
    return aid, response.json()["id"]


def read(api, path: str, who="alice", tag: str | None = None, **headers):
    if tag:
        headers["If-None-Match"] = tag
    return api.client.get(path, headers=api.as_(who) | headers)


def tags(api, sid, who="alice", **headers) -> dict[str, str]:
    out = {}
    for pattern in READS:
        response = read(api, pattern.format(sid=sid), who, **headers)
        assert response.status_code == 200, response.text
        out[pattern] = response.headers["etag"]
    return out


def test_an_unchanged_complete_report_answers_304_with_no_body_on_every_read(api):
    _, sid = graded(api)
    for pattern, tag in tags(api, sid).items():
        path = pattern.format(sid=sid)
        again = read(api, path, tag=tag)
        assert again.status_code == 304, (path, again.status_code)
        assert again.content == b"" and again.headers["etag"] == tag
        assert again.headers["cache-control"] == "private, no-cache"  # kept by the browser, asked again each time
        # A weak form of the same tag, or a list holding it, matches too; another tag is answered in full.
        assert read(api, path, tag=f'"x", W/{tag}').status_code == 304
        full = read(api, path, tag='"not-this-one"')
        assert full.status_code == 200 and full.headers["etag"] == tag and full.content
    # The cached page is the page: the same bytes as one built afresh.
    from grader.web.etag import BODIES

    cached = read(api, f"/submissions/{sid}").text
    BODIES.clear()
    assert read(api, f"/submissions/{sid}").text == cached


def test_release_of_a_withheld_item_changes_every_etag_so_a_304_never_hides_it(api):
    aid, sid = graded(api, item_visibility={"C2": "on_release"})
    before = tags(api, sid)
    page = read(api, f"/submissions/{sid}").text
    assert "1 of 8 points pending" in page
    assert api.client.post(f"/v1/assignments/{aid}/release", headers=api.as_("prof")).status_code == 200
    for pattern, tag in before.items():
        after = read(api, pattern.format(sid=sid), tag=tag)
        assert after.status_code == 200, pattern
        assert after.headers["etag"] != tag
    assert "points pending" not in read(api, f"/submissions/{sid}", tag=before["/submissions/{sid}"]).text


def test_an_override_and_a_regrade_each_change_the_etag(api):
    _, sid = graded(api)
    first = tags(api, sid)
    made = api.client.post(f"/v1/submissions/{sid}/overrides", headers=api.as_("prof"),
                           json={"item_id": "C2", "score": 0, "comment": "The reason quotes the wrong condition."})
    assert made.status_code == 201, made.text
    second = tags(api, sid)
    assert all(second[p] != first[p] for p in READS)
    published = api.client.post("/v1/rubrics/versions", json=rubric_v3(), headers=api.as_("prof"))
    assert published.status_code == 201, published.text
    preview = api.client.get("/v1/courses/l03/regrade-preview?version=3", headers=api.as_("prof")).json()
    commit = api.client.post("/v1/courses/l03/regrades", headers=api.as_("prof"),
                             json={"version": "3", "content_hash": preview["content_hash"]})
    assert commit.status_code == 201, commit.text
    for pattern, tag in second.items():
        response = read(api, pattern.format(sid=sid), tag=tag)
        assert response.status_code == 200 and response.headers["etag"] != tag, pattern
    assert read(api, f"/v1/submissions/{sid}/grade").json()["rubric_version"] == "3"


def test_a_language_switch_changes_the_page_etag_and_the_page(api):
    _, sid = graded(api)
    english = read(api, f"/submissions/{sid}")
    chinese = read(api, f"/submissions/{sid}", tag=english.headers["etag"], **{"Accept-Language": "zh-CN"})
    assert chinese.status_code == 200 and chinese.headers["etag"] != english.headers["etag"]
    assert chinese.text != english.text and 'lang="zh' in chinese.text
    assert read(api, f"/submissions/{sid}", tag=chinese.headers["etag"],
                **{"Accept-Language": "zh-CN"}).status_code == 304


def test_two_readers_never_share_a_cached_body_or_an_etag(api):
    _, sid = graded(api)
    mine = read(api, f"/submissions/{sid}", "alice")
    staff = read(api, f"/submissions/{sid}", "prof")  # rendered after alice's is cached
    assert mine.headers["etag"] != staff.headers["etag"]
    assert staff.text != mine.text
    # The instructor's page is theirs (their name, the override form); alice's tag opens nothing for them.
    assert read(api, f"/submissions/{sid}", "prof", tag=mine.headers["etag"]).status_code == 200
    again = read(api, f"/submissions/{sid}", "alice")
    assert again.text == mine.text and again.headers["etag"] == mine.headers["etag"]
    # Someone who may not read the submission gets the 404 page, never the cached report.
    outsider = read(api, f"/submissions/{sid}", "bob", tag=mine.headers["etag"])
    assert outsider.status_code == 404 and "etag" not in outsider.headers


@pytest.mark.lesson_unmeasured
def test_a_report_not_complete_carries_no_etag(api):
    aid = create(api).json()["id"]
    response = submit(api, aid)
    assert response.status_code == 202 and response.json()["status"] != "graded", response.text
    sid = response.json()["id"]
    for path in (f"/submissions/{sid}", f"/v1/submissions/{sid}"):
        answer = read(api, path, tag="*")
        assert answer.status_code == 200 and "etag" not in answer.headers, path
