"""Scores sent to the LMS on their own (grader.services.lti.outbox): a grade stored marks its assignment in the same
transaction, the reconciler's pass (grader.reconcile.find_and_requeue) sends it to lti1p3platform's gradebook over
HTTP on loopback, a refused send backs off and shows on the instructor's LTI page, and a withheld score waits for the
release. No test here calls a "send": the pass does."""

from __future__ import annotations

import time
from datetime import timedelta
from types import SimpleNamespace

from sqlalchemy import select

from tests.grader.services.setup.test_assignments import create
from tests.grader.services.lti.test_lti import _session, launch_form, platform, post_launch  # noqa: F401 - `platform` fixture

STUDENT = "lms-user-17"


class _Report:
    """A grade report as rubric.grade_sheet returns one, reduced to what storing a grade reads."""

    def __init__(self, total: float, max_total: float):
        self.total, self.max_total = total, max_total

    def model_dump(self, mode: str = "json") -> dict:
        return {"total": self.total, "max_total": self.max_total, "items": []}


BOOK = SimpleNamespace(lesson="L03", version=2, content_hash="x" * 64)


def grade(aid: int, attempt: int, total: float, max_total: float = 10.0) -> int:
    """A graded attempt of the LMS student, stored by grader.core.grading.store_grade (the one place grades are
    stored: the worker and a regrade call it), committed as the worker commits it."""
    from grader.core.grading import store_grade
    from grader.core.models import LtiIdentity, Submission

    with _session() as session:
        user = session.scalar(select(LtiIdentity).where(LtiIdentity.sub == STUDENT)).user
        submission = Submission(course_id=user.course_id, student_id=user.id, lesson="L03", sheet={},
                                status="grading", assignment_id=aid, attempt=attempt, late_seconds=0)
        session.add(submission)
        session.flush()
        store_grade(session=session, submission=submission, book=BOOK, report=_Report(total, max_total),
                    execution_s=0.1, complete=True)
        session.commit()
        return submission.id


def sweep(now=None) -> list:
    """One reconciler pass, as `grader reconcile` and the embedded service run it; what it sent to the LMS."""
    from grader.reconcile import find_and_requeue

    with _session() as session:
        return find_and_requeue(session=session, now=now).scores


def outbox(aid: int):
    from grader.core.models import LtiOutbox

    with _session() as session:
        return session.scalar(select(LtiOutbox).where(LtiOutbox.assignment_id == aid))


def launched(api, lms, **assignment) -> int:
    """An assignment of l03, the LMS student launched once (the tool learns the course's gradebook)."""
    lms.tool_jwks = api.client.get("/lti/jwks").json()
    aid = create(api, **assignment).json()["id"]
    assert post_launch(api, launch_form(api, lms, STUDENT)).status_code == 200
    return aid


def gradebook(lms) -> dict:
    return {user: s["scoreGiven"] for item in lms.line_items for user, s in item["scores"].items()}


def test_a_stored_grade_reaches_the_gradebook_on_the_next_pass_and_a_second_pass_sends_nothing(api, platform):
    aid = launched(api, platform)
    # The first launch made the course's gradebook known: its assignments are due once (nothing graded yet).
    assert [(p.assignment_id, p.counts) for p in sweep()] == [(aid, {})]
    assert sweep() == [] and outbox(aid).due_at is None
    grade(aid, 1, 7.0)
    assert outbox(aid).due_at is not None  # marked with the grade, before any pass
    (sent,) = sweep()
    assert (sent.assignment_id, sent.counts, sent.error, sent.next_try_at) == (aid, {"sent": 1}, None, None)
    assert gradebook(platform) == {STUDENT: 7.0}
    delivered = platform.line_items[0]["scores"][STUDENT]
    assert sweep() == []  # idempotent: nothing due, nothing posted
    assert platform.line_items[0]["scores"][STUDENT] is delivered
    grade(aid, 2, 9.0)  # the latest attempt counts: the changed score goes
    assert [p.counts for p in sweep()] == [{"sent": 1}]
    assert gradebook(platform) == {STUDENT: 9.0} and len(platform.line_items) == 1


def test_a_second_mark_of_an_unchanged_score_posts_nothing(api, platform):
    from grader.core.lti_outbox import mark

    aid = launched(api, platform)
    grade(aid, 1, 5.0)
    sweep()
    delivered = platform.line_items[0]["scores"][STUDENT]
    with _session() as session:
        mark(session=session, assignment_ids=[aid])
        session.commit()
    assert [p.counts for p in sweep()] == [{"unchanged": 1}]
    assert platform.line_items[0]["scores"][STUDENT] is delivered


def test_a_refused_send_backs_off_shows_on_the_page_and_the_retry_delivers(api, platform):
    from grader.core.models import utcnow

    aid = launched(api, platform)
    platform.refuse_scores = True  # the gradebook answers 503
    grade(aid, 1, 6.0)
    before = utcnow()
    (failed,) = sweep()
    assert failed.counts == {"failed": 1} and "503" in failed.error
    assert timedelta(seconds=59) < failed.next_try_at - before < timedelta(seconds=70)  # the first backoff, 60 s
    assert sweep() == []  # backing off: the next pass leaves it alone
    row = outbox(aid)
    assert row.attempts == 1 and "503" in row.last_error
    api.client.post("/sign-in", data={"token": api.tokens["prof"]})
    page = api.client.get("/courses/l03/lti")
    assert page.status_code == 200
    assert 'id="outbox-%d"' % aid in page.text and "answered HTTP 503" in page.text and "failed" in page.text
    assert "gradebook down" not in page.text and "gradebook down" not in row.last_error  # the platform's body: never
    assert "Scores the LMS has not received" in page.text
    assert "grader_lti_sends_failing 1.0" in api.client.get("/metrics").text  # the operator sees it too
    # Still down at the next try: the wait doubles.
    (again,) = sweep(now=failed.next_try_at + timedelta(seconds=1))
    assert again.error and outbox(aid).attempts == 2
    assert timedelta(seconds=119) < again.next_try_at - failed.next_try_at < timedelta(seconds=125)
    platform.refuse_scores = False
    (retried,) = sweep(now=again.next_try_at + timedelta(seconds=1))
    assert (retried.counts, retried.error, retried.next_try_at) == ({"sent": 1}, None, None)
    assert gradebook(platform) == {STUDENT: 6.0}
    assert (outbox(aid).attempts, outbox(aid).last_error) == (0, None)
    page = api.client.get("/courses/l03/lti")
    assert "answered HTTP 503" not in page.text and 'id="nothing-due"' in page.text
    assert "grader_lti_sends_failing 0.0" in api.client.get("/metrics").text


def test_retry_now_sends_at_once_whatever_the_backoff(api, platform):
    aid = launched(api, platform)
    platform.refuse_scores = True
    grade(aid, 1, 4.0)
    assert sweep()[0].error
    platform.refuse_scores = False
    api.client.post("/sign-in", data={"token": api.tokens["prof"]})
    answer = api.client.post("/courses/l03/lti/retry", follow_redirects=False)
    assert answer.status_code == 303 and answer.headers["location"] == "/courses/l03/lti?retried=1#sends"
    assert gradebook(platform) == {STUDENT: 4.0}
    page = api.client.get(answer.headers["location"])
    assert 'id="retried"' in page.text and 'id="nothing-due"' in page.text


def test_a_withheld_item_never_reaches_the_gradebook_before_release(api, platform):
    aid = launched(api, platform, item_visibility={"C3": "on_release"})
    grade(aid, 1, 8.0)
    (waiting,) = sweep()
    assert waiting.counts == {"withheld": 1} and waiting.next_try_at is None  # the release marks it, no timer
    assert gradebook(platform) == {} and "withheld" in outbox(aid).waiting
    grade(aid, 2, 9.0)
    sweep()
    assert gradebook(platform) == {}  # a new grade before the release: still nothing
    assert api.client.post(f"/v1/assignments/{aid}/release", headers=api.as_("prof")).status_code == 200
    (released,) = sweep()
    assert released.counts == {"sent": 1} and gradebook(platform) == {STUDENT: 9.0}
    assert outbox(aid).waiting is None


def test_a_score_shown_after_the_due_date_goes_on_the_first_pass_after_it(api, platform):
    from grader.core.models import Assignment, utcnow

    aid = launched(api, platform, visibility="after_due")
    due = utcnow() + timedelta(seconds=3)
    with _session() as session:
        session.get(Assignment, aid).due_at = due
        session.commit()
    grade(aid, 1, 3.0)
    (waiting,) = sweep()
    assert waiting.counts == {"withheld": 1} and abs((waiting.next_try_at - due).total_seconds()) < 1
    assert sweep() == [] and gradebook(platform) == {}
    time.sleep(max(0.0, (due - utcnow()).total_seconds()) + 0.2)
    (shown,) = sweep()
    assert shown.counts == {"sent": 1} and gradebook(platform) == {STUDENT: 3.0}


def test_a_course_without_a_gradebook_marks_nothing(api):
    aid = create(api).json()["id"]
    from grader.core.db import new_session
    from grader.core.grading import store_grade
    from grader.core.models import Submission, User

    with new_session() as session:
        alice = session.scalar(select(User).where(User.name == "alice"))
        submission = Submission(course_id=alice.course_id, student_id=alice.id, lesson="L03", sheet={},
                                status="grading", assignment_id=aid, attempt=1, late_seconds=0)
        session.add(submission)
        session.flush()
        store_grade(session=session, submission=submission, book=BOOK, report=_Report(1.0, 10.0), execution_s=0.1,
                    complete=True)
        session.commit()
    assert outbox(aid) is None and sweep() == []


def test_only_the_courses_instructors_see_the_lti_page(api, platform):
    launched(api, platform)
    for who in ("alice", "tess", "eve"):
        api.client.post("/sign-out")
        api.client.post("/sign-in", data={"token": api.tokens[who]})
        assert api.client.get("/courses/l03/lti").status_code in (403, 404), who
        assert api.client.post("/courses/l03/lti/retry", follow_redirects=False).status_code in (403, 404), who
    api.client.post("/sign-out")
    api.client.post("/sign-in", data={"token": api.tokens["prof"]})
    page = api.client.get("/courses/l03/lti")
    assert page.status_code == 200 and platform.issuer in page.text and "course-ctx-1" in page.text
    assert 'href="/courses/l03/lti"' in api.client.get("/submissions").text  # the instructor's header links it


def test_a_platform_that_gives_only_the_links_line_item_gets_the_scores_there(api, platform):
    """A platform that lets the tool post scores to the link's own column only (the AGS claim has `lineitem`, no
    `lineitems`, and the score scope alone): a stored grade reaches that column on the next pass."""
    score_scope = "https://purl.imsglobal.org/spec/lti-ags/scope/score"
    platform.tool_jwks = api.client.get("/lti/jwks").json()
    aid = create(api).json()["id"]
    platform.links["link-1"] = {"assignment_id": str(aid)}
    platform.line_items.append({"id": f"{platform.url}/lineitems/0", "label": "the LMS's column", "scores": {}})
    platform.override = {"https://purl.imsglobal.org/spec/lti-ags/claim/endpoint": {
        "scope": [score_scope], "lineitem": f"{platform.url}/lineitems/0"}}
    assert post_launch(api, launch_form(api, platform, STUDENT)).status_code == 200
    grade(aid, 1, 3.5)
    assert outbox(aid).due_at is not None  # the link's column is a gradebook: the grade marks its assignment
    assert [p.counts for p in sweep()] == [{"sent": 1}]
    assert gradebook(platform) == {STUDENT: 3.5} and len(platform.line_items) == 1
    assert platform.token_scopes == [score_scope]
