"""Cross-site form posts are refused by origin (issue 26): Sec-Fetch-Site, else Origin, as Go's
CrossOriginProtection; requests without browser headers (the CLI, curl) pass. Over the real app in-process."""

from __future__ import annotations

import re

import pytest
from sqlalchemy import select

from grader.core.db import new_session
from grader.core.models import WebSession
from tests.factories import rubric_v3

CROSS_SITE = {"Origin": "https://evil.example", "Sec-Fetch-Site": "cross-site"}
COOKIE = "grader_session"


def _sign_in(api, who: str) -> str:
    api.client.cookies.clear()
    signed = api.client.post("/sign-in", data={"token": api.tokens[who]}, follow_redirects=False)
    assert signed.status_code == 303, signed.text
    return api.client.cookies[COOKIE]


def _refused(response) -> bool:
    return response.status_code == 403 and "cross-site request refused" in response.text


def test_a_cross_site_sign_in_is_refused_and_signs_nobody_in(api):
    # The attack: another site's form posts the attacker's token, and the victim browses as the attacker.
    response = api.client.post("/sign-in", data={"token": api.tokens["eve"]}, headers=CROSS_SITE,
                               follow_redirects=False)
    assert _refused(response) and "Sec-Fetch-Site" in response.text, response.text
    assert "set-cookie" not in response.headers
    with new_session() as session:
        assert session.scalars(select(WebSession)).all() == []


def test_a_cross_site_regrade_commit_is_refused_and_a_same_origin_one_commits(api):
    assert api.client.post("/v1/rubrics/versions", json=rubric_v3(), headers=api.as_("prof")).status_code == 201
    preview = api.client.get("/v1/courses/l03/regrade-preview?version=3", headers=api.as_("prof")).json()
    form = {"version": "3", "lesson": "L03", "content_hash": preview.get("content_hash", "")}
    _sign_in(api, "prof")
    response = api.client.post("/courses/l03/regrade", data=form, headers=CROSS_SITE, follow_redirects=False)
    assert _refused(response), response.text
    assert api.client.get("/v1/courses/l03/regrades", headers=api.as_("prof")).json() == []
    ours = api.client.post("/courses/l03/regrade", data=form, headers={"Origin": "http://testserver",
                                                                       "Sec-Fetch-Site": "same-origin"},
                           follow_redirects=False)
    assert ours.status_code == 303, ours.text
    assert len(api.client.get("/v1/courses/l03/regrades", headers=api.as_("prof")).json()) == 1


def test_a_cross_site_sign_out_is_refused_and_the_session_stays(api):
    cookie = _sign_in(api, "alice")
    assert _refused(api.client.post("/sign-out", headers={"Sec-Fetch-Site": "same-site"}, follow_redirects=False))
    assert api.client.cookies[COOKIE] == cookie
    assert api.client.get("/submissions", follow_redirects=False).status_code == 200


@pytest.mark.parametrize("headers, allowed", [
    ({}, True),  # no browser headers: the CLI, curl
    ({"Sec-Fetch-Site": "same-origin"}, True),
    ({"Sec-Fetch-Site": "none"}, True),  # the user typed it
    ({"Sec-Fetch-Site": "same-origin", "Origin": "https://evil.example"}, True),  # Sec-Fetch-Site decides
    ({"Sec-Fetch-Site": "same-site"}, False),  # a sibling subdomain is another site's page
    ({"Sec-Fetch-Site": "cross-site"}, False),
    ({"Origin": "http://testserver"}, True),  # an older browser: Origin is this host
    ({"Origin": "https://testserver"}, True),  # behind a TLS proxy the app sees http
    ({"Origin": "https://evil.example"}, False),
    ({"Origin": "http://testserver.evil.example"}, False),
    ({"Origin": "http://testserver:8080"}, False),
    ({"Origin": "null"}, False),  # a sandboxed frame or a data: URL
])
def test_the_origin_rule(api, headers, allowed):
    response = api.client.post("/sign-in", data={"token": api.tokens["alice"]}, headers=headers,
                               follow_redirects=False)
    assert (response.status_code == 303) is allowed and _refused(response) is not allowed, response.text


def test_every_unsafe_page_route_is_checked(api):
    from fastapi.routing import iter_route_contexts

    from grader.main import app

    unsafe = [(method, route.path) for route in iter_route_contexts(app.routes) if route.methods
              and not route.path.startswith("/v1")
              and route.path not in ("/lti/login", "/lti/launch")  # cross-site by design: a signed LTI launch
              for method in route.methods - {"GET", "HEAD", "OPTIONS"}]
    assert ("POST", "/sign-in") in unsafe and ("POST", "/courses/{course}/regrade") in unsafe
    _sign_in(api, "prof")
    for method, path in unsafe:
        url = re.sub(r"\{[a-z_]*id\}", "1", path.replace("{course}", "l03")).replace("{", "").replace("}", "")
        response = api.client.request(method, url, headers=CROSS_SITE, follow_redirects=False)
        assert _refused(response), (method, path, response.status_code)


def test_safe_requests_from_other_sites_still_open_pages(api):
    _sign_in(api, "alice")
    assert api.client.get("/submissions", headers=CROSS_SITE).status_code == 200  # a link from elsewhere
