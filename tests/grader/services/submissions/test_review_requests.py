"""Review requests over the real app in-process (SQLite): a student asks about one item shown to them, at most one open
request per item; instructors answer from the API or the queue page, with or without an override; the student reads
the answer on the report; answered requests are kept and listed; the dashboard shows what is open at its top."""

from __future__ import annotations

import re

import pytest

from tests.grader.services.setup.test_assignments import create, submit
from tests.grader.services.setup.test_assignments import lesson_cases_stored  # noqa: F401 - autouse: the lesson measured

MESSAGE = "My C3 answer names the small-dt run as the stable one, which the measured proxy shows. Please look again."
ANSWER = "Agreed: your reason is right, the marking rule reads the wrong field. Full point."


def graded(api, **assignment) -> tuple[int, int]:
    aid = create(api, **assignment).json()["id"]
    response = submit(api, aid)
    assert response.json()["status"] == "graded", response.text
    return aid, response.json()["id"]


def ask(api, sid, who="alice", **body):
    return api.client.post(f"/v1/submissions/{sid}/review-requests",
                           json={"item_id": "C3", "message": MESSAGE} | body, headers=api.as_(who))


def answer(api, rid, who="prof", **body):
    return api.client.post(f"/v1/review-requests/{rid}/answer", json={"answer": ANSWER} | body, headers=api.as_(who))


def sign_in(api, who: str) -> None:
    api.client.post("/sign-out")
    api.client.post("/sign-in", data={"token": api.tokens[who], "next": "/submissions"})


def test_one_open_request_per_item_and_answered_ones_are_kept(api):
    _, sid = graded(api)
    made = ask(api, sid)
    assert made.status_code == 201, made.text
    body = made.json()
    assert (body["item_id"], body["student"], body["state"], body["answer"]) == ("C3", "alice", "open", None)
    again = ask(api, sid, message="Still waiting.")
    assert again.status_code == 409
    assert again.json()["errors"] == [{"field": "item_id", "rule": (
        "at most one open review request per item: item C3 already has one; wait for its answer")}]
    assert ask(api, sid, item_id="C4").status_code == 201  # another item is its own request
    answered = answer(api, body["id"])
    assert answered.status_code == 200, answered.text
    assert (answered.json()["state"], answered.json()["answered_by"], answered.json()["override_id"]) == (
        "answered", "prof", None)
    assert answer(api, body["id"]).status_code == 409  # answered once
    assert ask(api, sid, message="A new question on C3.").status_code == 201  # closed: a new one may open
    listed = api.client.get(f"/v1/submissions/{sid}/review-requests", headers=api.as_("alice")).json()
    assert [(r["item_id"], r["state"]) for r in listed] == [("C3", "answered"), ("C4", "open"), ("C3", "open")]
    assert listed[0]["answer"] == ANSWER
    queue = api.client.get("/v1/courses/l03/review-requests", headers=api.as_("tess")).json()
    assert [r["item_id"] for r in queue] == ["C4", "C3"]  # open ones, oldest first
    kept = api.client.get("/v1/courses/l03/review-requests?state=answered", headers=api.as_("prof")).json()
    assert [r["id"] for r in kept] == [body["id"]]
    assert api.client.get("/v1/courses/l03/review-requests?state=closed", headers=api.as_("prof")).status_code == 422


@pytest.mark.parametrize("body, field, rule", [
    ({"item_id": "H1"}, "item_id", "must be an item of this grade shown to you (C1, C2"),
    ({"message": "  "}, "message", "required"),
])
def test_a_bad_request_names_the_field_and_nothing_is_stored(api, body, field, rule):
    _, sid = graded(api)
    response = ask(api, sid, **body)
    assert response.status_code == 422, response.text
    errors = {e["field"]: e["rule"] for e in response.json()["errors"]}
    assert field in errors and rule in errors[field], errors
    assert api.client.get(f"/v1/submissions/{sid}/review-requests", headers=api.as_("alice")).json() == []


def test_a_withheld_item_cannot_be_asked_about(api):
    _, sid = graded(api, item_visibility={"C3": "on_release"})
    response = ask(api, sid)
    assert response.status_code == 422
    (error,) = response.json()["errors"]
    assert error["field"] == "item_id" and error["rule"].startswith("item C3 is withheld: shown once “")
    assert ask(api, sid, item_id="C4").status_code == 201  # a shown item of the same grade may be asked about


@pytest.mark.parametrize("who, status", [("bob", 404), ("prof", 403), ("tess", 403), ("eve", 404)])
def test_only_the_submissions_student_asks(api, who, status):
    _, sid = graded(api)
    assert ask(api, sid, who=who).status_code == status


def test_who_may_read_the_queue_and_answer(api):
    _, sid = graded(api)
    rid = ask(api, sid).json()["id"]
    assert api.client.get("/v1/courses/l03/review-requests", headers=api.as_("alice")).status_code == 403
    assert api.client.get("/v1/courses/l03/review-requests", headers=api.as_("eve")).status_code == 404
    for who, status in (("alice", 403), ("tess", 403), ("eve", 404)):
        assert answer(api, rid, who=who).status_code == status, who
    empty = answer(api, rid, answer=" ")
    assert empty.status_code == 422 and empty.json()["errors"][0]["field"] == "answer"
    assert api.client.get("/v1/courses/l03/review-requests", headers=api.as_("prof")).json()[0]["state"] == "open"


def test_an_answer_with_an_override_changes_the_score_and_a_bad_score_stores_nothing(api):
    _, sid = graded(api)
    worse = api.client.get(f"/v1/submissions/{sid}/grade", headers=api.as_("alice")).json()
    rid = ask(api, sid).json()["id"]
    bad = answer(api, rid, score=3)
    assert bad.status_code == 422 and bad.json()["errors"][0]["field"] == "score"
    assert api.client.get("/v1/courses/l03/review-requests", headers=api.as_("prof")).json()[0]["id"] == rid
    assert len(api.client.get(f"/v1/submissions/{sid}/grades", headers=api.as_("prof")).json()) == 1
    done = answer(api, rid, score=0.5)
    assert done.status_code == 200, done.text
    assert done.json()["override_score"] == 0.5 and done.json()["override_id"]
    c3 = {i["id"]: i for i in api.client.get(f"/v1/submissions/{sid}/grade", headers=api.as_("alice")).json()["items"]}["C3"]
    assert (c3["score"], c3["measured_score"], c3["override"]["comment"]) == (0.5, 1, ANSWER)
    assert worse["total"] == 8 and api.client.get(f"/v1/submissions/{sid}", headers=api.as_("alice")).json()["total"] == 7.5


def test_the_pages_ask_answer_and_show_the_answer_and_the_dashboard_lists_what_is_open(api):
    _, sid = graded(api)
    sign_in(api, "alice")
    page = api.client.get(f"/submissions/{sid}").text
    assert 'id="review-request-form"' in page and 'id="override-form"' not in page
    asked = api.client.post(f"/submissions/{sid}/review-requests", data={"item_id": "C3", "message": MESSAGE},
                            follow_redirects=False)
    assert asked.status_code == 303, asked.text
    refused = api.client.post(f"/submissions/{sid}/review-requests", data={"item_id": "C3", "message": "again"})
    assert refused.status_code == 409 and "at most one open review request per item" in refused.text
    page = api.client.get(f"/submissions/{sid}").text
    assert MESSAGE in page and "open: waiting for an instructor" in page
    assert api.client.get("/courses/l03/reviews").status_code == 404  # a student never sees the queue
    sign_in(api, "prof")
    dashboard = api.client.get("/courses/l03/dashboard").text
    assert 'id="what-changed"' in dashboard and "alice asks about C3 of submission" in dashboard
    queue = api.client.get("/courses/l03/reviews")
    assert queue.status_code == 200 and MESSAGE in queue.text
    rid = api.client.get("/v1/courses/l03/review-requests", headers=api.as_("prof")).json()[0]["id"]
    missing = api.client.post(f"/courses/l03/reviews/{rid}/answer", data={"answer": "", "score": ""})
    assert missing.status_code == 422 and "Your answer: required" in missing.text
    bad = api.client.post(f"/courses/l03/reviews/{rid}/answer", data={"answer": ANSWER, "score": "many"})
    assert bad.status_code == 422 and "New score: must be a number of points" in bad.text
    done = api.client.post(f"/courses/l03/reviews/{rid}/answer", data={"answer": ANSWER, "score": "0.5"},
                           follow_redirects=False)
    assert done.status_code == 303 and done.headers["location"].startswith(f"/courses/l03/reviews?answered={rid}")
    queue = api.client.get(f"/courses/l03/reviews?answered={rid}").text
    assert 'id="no-open"' in queue and f'id="answered-{rid}"' in queue and "set to 0.5" in queue
    dashboard = api.client.get("/courses/l03/dashboard").text
    assert f"C3 of submission {sid} set to 0.5" in dashboard and "measured credit" in dashboard
    # The instructor's override form on the report page.
    report = api.client.get(f"/submissions/{sid}").text
    assert 'id="override-form"' in report and 'id="review-request-form"' not in report
    no_comment = api.client.post(f"/submissions/{sid}/overrides", data={"item_id": "C4", "score": "0.5",
                                                                       "comment": "  "})
    # the report again, the error beside the form by its label, what was typed kept (the item chosen, the score)
    assert no_comment.status_code == 422 and "Comment: required" in no_comment.text
    assert 'id="override-errors"' in no_comment.text and 'value="0.5"' in no_comment.text
    assert '<option value="C4" selected>' in no_comment.text and 'id="item-C4"' in no_comment.text
    # the queue shows the item as it stands now
    assert re.search(r'id="answered-\d+">.*?0\.5 of 1 points, <span class="verdict verdict-credit">credit</span>',
                     api.client.get("/courses/l03/reviews").text, re.S)
    set_ = api.client.post(f"/submissions/{sid}/overrides", data={"item_id": "C4", "score": "0",
                                                                  "comment": "C4 reason missing."},
                           follow_redirects=False)
    assert set_.status_code == 303 and set_.headers["location"] == f"/submissions/{sid}#override-C4"
    # The student reads the answer and the new score beside the measured verdict.
    sign_in(api, "alice")
    page = api.client.get(f"/submissions/{sid}").text
    assert ANSWER in page and "score set to 0.5" in page and "C4 reason missing." in page
    assert 'id="override-C3"' in page and "measured verdict; score set by an instructor" in page


def test_a_cross_site_override_or_review_request_is_refused_and_stores_nothing(api):
    _, sid = graded(api)
    cross = {"Sec-Fetch-Site": "cross-site"}
    sign_in(api, "prof")
    refused = api.client.post(f"/submissions/{sid}/overrides", headers=cross,
                              data={"item_id": "C3", "score": "0", "comment": "from another site"})
    assert refused.status_code == 403
    sign_in(api, "alice")
    refused = api.client.post(f"/submissions/{sid}/review-requests", headers=cross,
                              data={"item_id": "C3", "message": "from another site"})
    assert refused.status_code == 403
    assert api.client.get(f"/v1/submissions/{sid}/overrides", headers=api.as_("prof")).json() == []
    assert api.client.get(f"/v1/submissions/{sid}/review-requests", headers=api.as_("prof")).json() == []


def test_the_review_request_quota_is_the_students_over_all_their_submissions(api, monkeypatch):
    """The quota (settings.rate_limit_review_requests) counts a student's requests, not one submission's: spread over
    two graded attempts, the request past it is refused with 429 and the rule, and nothing more is stored; another
    student's requests are their own."""
    from grader.core.settings import settings

    monkeypatch.setattr(settings, "rate_limit_review_requests", "3/hour")
    aid, first = graded(api)
    second = submit(api, aid)
    assert second.json()["status"] == "graded", second.text
    second = second.json()["id"]
    for sid, item in ((first, "C3"), (first, "C4"), (second, "C3")):
        made = ask(api, sid, item_id=item)
        assert made.status_code == 201, (sid, item, made.text)
    refused = ask(api, second, item_id="C4")
    assert refused.status_code == 429 and int(refused.headers["Retry-After"]) >= 1, refused.text
    assert refused.json()["errors"] == [{"field": "review_requests",
                                         "rule": "at most 3 per 1 hour review requests per student"}]
    kept = api.client.get(f"/v1/submissions/{second}/review-requests", headers=api.as_("alice")).json()
    assert [r["item_id"] for r in kept] == ["C3"]
    bobs = submit(api, aid, who="bob")
    assert bobs.json()["status"] == "graded", bobs.text
    assert ask(api, bobs.json()["id"], who="bob").status_code == 201
