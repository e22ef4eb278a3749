"""The pages on the real app in-process: sign-in cookie, bearer header, who may see what, a report while grading."""

from __future__ import annotations

from tests.factories import reference_sheet


def _submit(api, who="alice") -> int:
    response = api.client.post("/v1/submissions", json={"sheet": reference_sheet() | {"student": who}},
                               headers=api.as_(who))
    assert response.status_code == 202, response.text
    return response.json()["id"]


def test_pages_redirect_to_sign_in_and_a_token_signs_in_with_an_httponly_cookie(api):
    submission = _submit(api)
    response = api.client.get(f"/submissions/{submission}", follow_redirects=False)
    assert response.status_code == 303 and response.headers["location"] == f"/sign-in?next=/submissions/{submission}"

    refused = api.client.post("/sign-in", data={"token": "not-a-token", "next": "/submissions"}, follow_redirects=False)
    assert refused.status_code == 401 and "unknown or has been revoked" in refused.text

    signed = api.client.post("/sign-in", data={"token": api.tokens["alice"], "next": f"/submissions/{submission}"},
                             follow_redirects=False)
    assert signed.status_code == 303 and signed.headers["location"] == f"/submissions/{submission}"
    cookie = signed.headers["set-cookie"].lower()
    assert cookie.startswith("grader_session=") and "httponly" in cookie and "samesite=strict" in cookie
    page = api.client.get(f"/submissions/{submission}")
    assert page.status_code == 200 and f"Submission {submission}: alice" in page.text
    api.client.post("/sign-out")
    assert api.client.get(f"/submissions/{submission}", follow_redirects=False).status_code == 303


def test_sign_in_never_redirects_off_the_site(api):
    signed = api.client.post("/sign-in", data={"token": api.tokens["alice"], "next": "//evil.example/x"},
                             follow_redirects=False)
    assert signed.headers["location"] == "/submissions"


def test_the_bearer_header_works_and_nobody_sees_what_they_may_not(api):
    submission = _submit(api)
    api.client.cookies.clear()
    assert api.client.get(f"/submissions/{submission}", headers=api.as_("alice")).status_code == 200
    assert api.client.get(f"/submissions/{submission}", headers=api.as_("prof")).status_code == 200  # her course
    for outsider in ("bob", "eve"):  # another student; an instructor of another course
        page = api.client.get(f"/submissions/{submission}", headers=api.as_(outsider))
        assert page.status_code == 404 and "alice" not in page.text and "N1" not in page.text
    missing = api.client.get("/submissions/999999", headers=api.as_("alice"))
    assert missing.status_code == 404
    huge = api.client.get(f"/submissions/{2**64}", headers=api.as_("alice"))
    assert huge.status_code in (404, 422) and "Traceback" not in huge.text
    listed = api.client.get("/submissions", headers=api.as_("bob"))
    assert listed.status_code == 200 and f'href="/submissions/{submission}"' not in listed.text


def test_a_report_while_grading_lists_every_case_run_queued_and_refreshes(api):
    submission = _submit(api)
    page = api.client.get(f"/submissions/{submission}", headers=api.as_("alice"))
    runs = api.client.get(f"/v1/submissions/{submission}/case-runs", headers=api.as_("alice")).json()
    assert runs and all(f"<td>{run['name']}</td>" in page.text for run in runs)
    assert page.text.count("state state-queued") == len(runs)
    assert '<meta http-equiv="refresh" content="3">' in page.text and "Grading in progress" in page.text


def test_the_stylesheet_is_served_by_the_app(api):
    css = api.client.get("/static/style.css")
    assert css.status_code == 200 and css.headers["content-type"].startswith("text/css") and ".verdict-credit" in css.text
    page = api.client.get("/sign-in")
    assert 'href="/static/style.css"' in page.text and "http://" not in page.text and "https://" not in page.text


def test_the_dashboard_is_for_the_courses_staff_only(api):
    _submit(api)
    assert api.client.get("/v1/courses/l03/dashboard", headers=api.as_("alice")).status_code == 403
    assert api.client.get("/v1/courses/l03/dashboard", headers=api.as_("eve")).status_code == 404
    data = api.client.get("/v1/courses/l03/dashboard", headers=api.as_("prof")).json()
    assert data["submissions_by_state"] == {"running": 1} and data["roster"][0]["student"] == "alice"
    assert data["analysis"]["n_reports"] == 0 and data["problems"] == []
    for who, code in (("alice", 404), ("eve", 404), ("prof", 200), ("tess", 200)):
        page = api.client.get("/courses/l03/dashboard", headers=api.as_(who))
        assert page.status_code == code, who
    page = api.client.get("/courses/l03/dashboard", headers=api.as_("prof"))
    assert "No graded submissions yet." in page.text and "alice" in page.text


def test_results_json_is_there_once_graded_and_only_for_who_may_read_it(api):
    submission = _submit(api)
    # Not graded yet: nothing to download, and the page says so rather than failing.
    assert api.client.get(f"/submissions/{submission}/results.json", headers=api.as_("alice")).status_code == 404
    assert api.client.get(f"/submissions/{submission}/results.json", headers=api.as_("bob")).status_code == 404
