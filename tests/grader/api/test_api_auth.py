"""Tokens and roles on the real app: no token 401, students see only their own, instructors their course."""

from __future__ import annotations

import pytest

from tests.factories import reference_sheet


@pytest.fixture
def alices(api):
    response = api.client.post("/v1/submissions", json={"sheet": reference_sheet()}, headers=api.as_("alice"))
    assert response.status_code == 202, response.text
    return response.json()


def test_health_and_docs_need_no_token(api):
    assert api.client.get("/v1/health").json()["status"] == "ok"
    assert api.client.get("/openapi.json").status_code == 200


@pytest.mark.parametrize("headers", [{}, {"Authorization": "Bearer not-a-token"}, {"Authorization": "Basic eDp5"}])
def test_calls_without_a_valid_token_get_401(api, headers):
    for method, path in (("get", "/v1/submissions"), ("get", "/v1/submissions/1"),
                         ("post", "/v1/submissions"), ("get", "/v1/courses/l03/submissions")):
        response = getattr(api.client, method)(path, headers=headers)
        assert response.status_code == 401, (path, response.text)
        assert response.json()["detail"] and response.headers["www-authenticate"] == "Bearer"


def test_only_the_hash_of_a_token_is_stored(api):
    from sqlalchemy import select

    from grader.core.db import new_session
    from grader.core.security import hash_token
    from grader.core.models import ApiToken

    with new_session() as session:
        stored = set(session.scalars(select(ApiToken.token_hash)))
    assert api.tokens["alice"] not in stored and hash_token(api.tokens["alice"]) in stored


def test_a_student_cannot_read_another_students_submission(api, alices):
    sid = alices["id"]
    for path in ("", "/grade", "/case-runs", "/events", "/case-runs/N1/files/arrays.npz", "/series"):
        response = api.client.get(f"/v1/submissions/{sid}{path}", headers=api.as_("bob"))
        assert response.status_code == 404, (path, response.text)
    assert api.client.get("/v1/submissions", headers=api.as_("bob")).json() == []
    assert [s["id"] for s in api.client.get("/v1/submissions", headers=api.as_("alice")).json()] == [sid]
    assert api.client.get(f"/v1/submissions/{sid}", headers=api.as_("alice")).status_code == 200


def test_instructors_and_auditors_see_their_course_only(api, alices):
    for who in ("prof", "tess"):
        listed = api.client.get("/v1/courses/l03/submissions", headers=api.as_(who))
        assert [s["id"] for s in listed.json()] == [alices["id"]]
        assert api.client.get(f"/v1/submissions/{alices['id']}/case-runs", headers=api.as_(who)).status_code == 200
    assert api.client.get("/v1/courses/l03/submissions", headers=api.as_("alice")).status_code == 403
    assert api.client.get("/v1/courses/l03/submissions", headers=api.as_("eve")).status_code == 404
    assert api.client.get(f"/v1/submissions/{alices['id']}", headers=api.as_("eve")).status_code == 404


def test_an_auditor_cannot_submit(api):
    response = api.client.post("/v1/submissions", json={"sheet": reference_sheet()}, headers=api.as_("tess"))
    assert response.status_code == 403
