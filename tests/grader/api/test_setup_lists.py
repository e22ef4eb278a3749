"""The API's lists of a course's set-up (issue 33): its roster, an assignment's extensions and its record of changes;
staff of the course read them, a student is refused (403), anyone of another course finds nothing (404)."""

from __future__ import annotations

import pytest

pytestmark = pytest.mark.clock("2026-11-27T12:00:00Z")
CSV = "student_id,name,email\ns1001,Ada Lovelace,ada@example.edu\ns1002,Zhang Wei 张伟,wei@example.edu\n"


@pytest.fixture
def course(api):
    """An assignment with one extension, a roster import and a settings change in course l03."""
    created = api.client.post("/v1/courses/l03/assignments", headers=api.as_("prof"), json={
        "title": "Checkpoints", "part": "checkpoints", "open_at": "2020-01-01T00:00:00Z",
        "due_at": "2099-01-01T00:00:00Z", "hard_close_at": "2099-01-02T00:00:00Z"})
    assert created.status_code == 201, created.text
    aid = created.json()["id"]
    assert api.client.post("/v1/courses/l03/roster", headers=api.as_("prof"), json={"csv": CSV}).status_code == 200
    granted = api.client.post(f"/v1/assignments/{aid}/extensions", headers=api.as_("prof"), json={
        "student": "s1002", "due_at": "2099-01-05T00:00:00Z", "hard_close_at": "2099-01-06T00:00:00Z"})
    assert granted.status_code == 201, granted.text
    patched = api.client.patch("/v1/courses/l03", headers=api.as_("prof"), json={"free_submissions": False})
    assert patched.status_code == 200, patched.text
    return aid


def test_staff_list_the_roster_without_tokens(api, course):
    for who in ("prof", "tess"):
        listed = api.client.get("/v1/courses/l03/roster", headers=api.as_(who))
        assert listed.status_code == 200, listed.text
        rows = {r["student"]: r for r in listed.json()}
        assert rows["s1002"] == {"student": "s1002", "name": "Zhang Wei 张伟", "email": "wei@example.edu"}
        assert {"alice", "bob", "s1001", "s1002"} <= set(rows) and "prof" not in rows and "tess" not in rows
        assert "token" not in listed.text and "sign-in" not in listed.text


def test_staff_list_an_assignments_extensions(api, course):
    for who in ("prof", "tess"):
        listed = api.client.get(f"/v1/assignments/{course}/extensions", headers=api.as_(who))
        assert listed.status_code == 200, listed.text
        assert listed.json() == [{"assignment_id": course, "student": "s1002", "due_at": "2099-01-05T00:00:00Z",
                                  "hard_close_at": "2099-01-06T00:00:00Z", "granted_by": "prof",
                                  "granted_at": listed.json()[0]["granted_at"]}]


def test_staff_list_the_change_log_newest_first(api, course):
    listed = api.client.get("/v1/courses/l03/changes", headers=api.as_("tess"))
    assert listed.status_code == 200, listed.text
    kinds = [c["kind"] for c in listed.json()]
    assert kinds == ["course_settings", "extension_granted", "roster_imported", "assignment_created"]
    newest = listed.json()[0]
    assert (newest["by"], newest["detail"], newest["assignment_id"]) == ("prof", {"free_submissions": [True, False]},
                                                                        None)
    assert listed.json()[1]["assignment_id"] == course


@pytest.mark.parametrize("path", ["/v1/courses/l03/roster", "/v1/courses/l03/changes",
                                  "/v1/assignments/{aid}/extensions"])
def test_students_are_refused_and_other_courses_find_nothing(api, course, path):
    path = path.format(aid=course)
    assert api.client.get(path, headers=api.as_("alice")).status_code == 403
    assert api.client.get(path, headers=api.as_("eve")).status_code == 404
    assert api.client.get(path).status_code == 401
