"""One limit at every door (issue 31, item 2): the submission rate is counted by the service the API and the sheet
form both call, so ten form submissions leave none for the API and the eleventh is refused with the API's 429 and
rule; draft saves and review requests per person, wrong sign-ins and unknown sign-in links per client address are
counted in the same shared store, and a page answers the refusal as HTML with Retry-After."""

from __future__ import annotations

import html

from fastapi.testclient import TestClient

from grader.main import app
from grader.core.settings import settings
from tests.factories import REFERENCE_YAML
from tests.grader.pages.test_sheet_form import form_fields, import_yaml
from tests.grader.pages.test_submit_confirm import confirm_fields

RULE = "at most 10 per 1 minute submissions per person"


def form_submit(api, fields: dict, who: str = "alice"):
    """The sheet form's submit, then its confirmation's button: what a student presses twice."""
    shown = api.client.post("/sheet", headers=api.as_(who), data={**fields, "action": "submit"})
    assert shown.status_code == 200, shown.text
    return api.client.post("/sheet", headers=api.as_(who), data=confirm_fields(shown.text), follow_redirects=False)


def test_ten_form_submissions_then_the_eleventh_is_refused_with_the_apis_429_and_rule(api, monkeypatch):
    monkeypatch.setattr(settings, "rate_limit_submissions", "10/minute")
    monkeypatch.setattr(settings, "student_waiting_runs_max", 1000)  # the queue cap is another rule, not this one
    page = import_yaml(api, REFERENCE_YAML.read_text())
    fields = form_fields(page.text)
    for n in range(10):
        done = form_submit(api, fields)
        assert done.status_code == 303, (n, done.text[:2000])
    refused = form_submit(api, fields)
    assert refused.status_code == 429, refused.text[:2000]
    assert 1 <= int(refused.headers["Retry-After"]) <= 60
    assert 'id="check-summary"' in refused.text and refused.text.count(html.escape(RULE)) == 1
    # The API's door counts in the same allowance and says the same rule.
    api_refused = api.client.post("/v1/submissions", json={"sheet": {}}, headers=api.as_("alice"))
    assert api_refused.status_code == 429, api_refused.text
    assert api_refused.json()["errors"] == [{"field": "submissions", "rule": RULE}]
    assert 1 <= int(api_refused.headers["Retry-After"]) <= 60
    # Another person has their own.
    assert form_submit(api, form_fields(import_yaml(api, REFERENCE_YAML.read_text(), who="bob").text),
                       who="bob").status_code == 303


def test_draft_saves_are_limited_per_person_and_a_page_answers_html_with_retry_after(api, monkeypatch):
    monkeypatch.setattr(settings, "rate_limit_draft_saves", "3/minute")
    fields = form_fields(api.client.get("/sheet", headers=api.as_("alice")).text)
    for value in ("increase", "decrease", "increase"):
        saved = api.client.post("/sheet/draft", headers=api.as_("alice"),
                                data={**fields, "answers.A2.direction": value})
        assert saved.status_code == 200 and saved.text.startswith("saved "), saved.text
    refused = api.client.post("/sheet/draft", headers=api.as_("alice"), data={**fields, "answers.A2.direction": "same"})
    assert refused.status_code == 429 and refused.headers["content-type"].startswith("text/html"), refused.text
    assert int(refused.headers["Retry-After"]) >= 1
    assert "at most 3 per 1 minute draft saves per person" in refused.text
    # The form's own save is a draft save too, refused beside the form; the draft is the last one taken.
    pressed = api.client.post("/sheet", headers=api.as_("alice"), data={**fields, "action": "save"})
    assert pressed.status_code == 429 and 'id="check-summary"' in pressed.text
    assert int(pressed.headers["Retry-After"]) >= 1
    kept = api.client.get("/sheet", headers=api.as_("alice")).text
    assert 'name="answers.A2.direction" value="increase" checked' in kept
    # Another person's saves are their own.
    assert api.client.post("/sheet/draft", headers=api.as_("bob"), data=fields).status_code == 200


def test_review_requests_are_limited_per_student_at_every_door(api, monkeypatch):
    """Counted before any other work (a request about a submission not graded yet counts too), through the API and
    the report page's form alike."""
    from tests.factories import reference_sheet

    monkeypatch.setattr(settings, "rate_limit_review_requests", "3/hour")
    sid = api.client.post("/v1/submissions", json={"sheet": reference_sheet()}, headers=api.as_("alice")).json()["id"]
    body = {"item_id": "C3", "message": "please look again"}
    for _ in range(2):
        asked = api.client.post(f"/v1/submissions/{sid}/review-requests", json=body, headers=api.as_("alice"))
        assert asked.status_code == 409, asked.text  # not graded yet, and counted
    paged = api.client.post(f"/submissions/{sid}/review-requests", data=body, headers=api.as_("alice"))
    assert paged.status_code == 409, paged.text
    refused = api.client.post(f"/v1/submissions/{sid}/review-requests", json=body, headers=api.as_("alice"))
    assert refused.status_code == 429 and int(refused.headers["Retry-After"]) >= 1, refused.text
    assert refused.json()["errors"] == [{"field": "review_requests",
                                         "rule": "at most 3 per 1 hour review requests per student"}]
    on_page = api.client.post(f"/submissions/{sid}/review-requests", data=body, headers=api.as_("alice"))
    assert on_page.status_code == 429 and "review requests per student" in on_page.text


def _client(address: str) -> TestClient:
    return TestClient(app, client=(address, 50000))


def test_wrong_sign_ins_are_limited_per_address_and_a_right_one_never_counts(api, monkeypatch):
    monkeypatch.setattr(settings, "rate_limit_sign_in_failures", "3/10 minutes")
    lab = _client("10.0.0.7")
    for _ in range(5):  # right tokens: never counted
        assert lab.post("/sign-in", data={"token": api.tokens["alice"]}, follow_redirects=False).status_code == 303
    for guess in range(3):
        wrong = lab.post("/sign-in", data={"token": f"guess-{guess}"}, follow_redirects=False)
        assert wrong.status_code == 401, wrong.text
    # Spent: the next try is refused before any token is looked up, the right one too, as a page with Retry-After.
    refused = lab.post("/sign-in", data={"token": api.tokens["alice"]}, follow_redirects=False)
    assert refused.status_code == 429 and refused.headers["content-type"].startswith("text/html"), refused.text
    assert int(refused.headers["Retry-After"]) >= 1 and "at most 3 per 10 minute failed sign-ins per address" in \
        refused.text
    assert "grader_session" not in refused.cookies
    # Another address is not held up by this one.
    assert _client("10.0.0.8").post("/sign-in", data={"token": api.tokens["alice"]},
                                    follow_redirects=False).status_code == 303


def test_unknown_sign_in_links_are_limited_per_address(api, monkeypatch):
    monkeypatch.setattr(settings, "rate_limit_link_guesses", "3/10 minutes")
    link = api.client.post("/v1/courses/l03/students/alice/sign-in-link", headers=api.as_("prof")).json()
    path = "/sign-in/link/" + link["sign_in_link"].rsplit("/", 1)[1]
    guesser = _client("10.0.0.9")
    assert guesser.get(path).status_code == 200  # a known link is never counted
    for n in range(2):
        assert guesser.get(f"/sign-in/link/{'A' * 42}{n}").status_code == 404
    assert guesser.post(f"/sign-in/link/{'B' * 43}", follow_redirects=False).status_code == 404
    for method in ("get", "post"):
        refused = getattr(guesser, method)(path, follow_redirects=False)
        assert refused.status_code == 429 and int(refused.headers["Retry-After"]) >= 1, refused.text
        assert "at most 3 per 10 minute unknown sign-in links per address" in refused.text
    # The link was not used up by the refusals: the student, from another address, signs in with it.
    assert _client("10.0.0.10").post(path, follow_redirects=False).status_code == 303
