"""Integrity rules no other test reached (issue 37, item 3): each test here fails when its one rule is taken out of
the code, which the rest of the suite let through. On the real app in-process (tests/grader/conftest.py); grades are
stored by grader.core.grading.store_grade from a real rubric.grade_sheet report of a checkpoint sheet, with the
verdicts its measured items would have (no Genesis run: the rules under test read the stored report only)."""

from __future__ import annotations

import itertools
import threading
from datetime import timedelta
from types import SimpleNamespace

import pytest
from sqlalchemy import func, select, update

from tests.grader.services.setup.test_assignments import ROSTER, checkpoint_sheet, create
from tests.grader.services.submissions.test_fair_queues import stored, submit as submit_sheet
from tests.grader.services.lti.test_lti import _refused, graded_attempt, launch_form, platform, post_launch, send  # noqa: F401
from tests.grader.services.lti.test_lti_outbox import grade as outbox_grade, launched, outbox, sweep

COMMENT = "The reason you gave holds once the stop is measured over the whole hold interval."


def _session():
    from grader.core.db import new_session

    return new_session()


# --- grades as the rubric stores them ------------------------------------------------------------------------------

def checkpoint_report(verdicts: dict[str, str] | None = None, points: dict[str, float] | None = None):
    """The rubric's report of alice's checkpoint sheet (rubric.grade_sheet), every item scored as `verdicts` says
    (default credit) the way the scorer scores a verdict: an inconclusive item neither credited nor counted (score
    and max_score 0). `points` gives items another worth, as a newer rubric version may."""
    from rubric import grade_sheet, parse_sheet

    report = grade_sheet(parse_sheet(checkpoint_sheet(), part="checkpoints"), {})
    items = []
    for item in report.items:
        worth = (points or {}).get(item.id, item.points)
        verdict = (verdicts or {}).get(item.id, "credit")
        items.append(item.model_copy(update={
            "points": worth, "verdict": verdict, "score": worth if verdict == "credit" else 0.0,
            "max_score": 0.0 if verdict == "inconclusive" else worth}))
    return report.model_copy(update={"items": items, "complete": True, "total": sum(i.score for i in items),
                                     "max_total": sum(i.max_score for i in items)})


def graded(aid: int, report, who: str = "alice") -> int:
    """A graded, complete submission of `who` to assignment `aid` holding `report`, stored as grading stores one."""
    from grader.core.grading import store_grade
    from grader.core.models import Submission, User

    with _session() as session:
        user = session.scalar(select(User).where(User.name == who))
        attempt = 1 + session.scalar(select(func.count()).select_from(Submission).where(
            Submission.assignment_id == aid, Submission.student_id == user.id))
        submission = Submission(course_id=user.course_id, student_id=user.id, lesson="L03", sheet=checkpoint_sheet(),
                                status="grading", assignment_id=aid, attempt=attempt, late_seconds=0)
        session.add(submission)
        session.flush()
        book = SimpleNamespace(lesson=report.lesson, version=report.rubric_version, content_hash=report.rubric_hash)
        store_grade(session=session, submission=submission, book=book, report=report, execution_s=0.1,
                    complete=True)
        session.commit()
        return submission.id


def grade_items(api, sid: int, who: str) -> tuple[dict, dict[str, dict]]:
    answer = api.client.get(f"/v1/submissions/{sid}/grade", headers=api.as_(who))
    assert answer.status_code == 200, answer.text
    return answer.json(), {i["id"]: i for i in answer.json()["items"]}


def override_rows(sid: int) -> int:
    from grader.core.models import Override

    with _session() as session:
        return session.scalar(select(func.count()).select_from(Override).where(Override.submission_id == sid))


# --- overrides: only an instructor, through the page's form too ---------------------------------------------------

@pytest.mark.parametrize("who", ["alice", "tess", "bob", "eve"])
def test_the_report_pages_override_form_changes_nothing_for_anyone_but_an_instructor(api, who):
    """The page route reads the submission (its student and the course's auditor may) and leaves the role to
    set_override: without that check, alice posting the form set her own C2."""
    aid = create(api).json()["id"]
    sid = graded(aid, checkpoint_report({"C2": "no_credit"}))
    form = {"item_id": "C2", "score": "1", "comment": COMMENT}
    answer = api.client.post(f"/submissions/{sid}/overrides", data=form, headers=api.as_(who),
                             follow_redirects=False)
    assert answer.status_code in (403, 404), answer.text
    assert override_rows(sid) == 0
    grade, items = grade_items(api, sid, "prof")
    assert (grade["total"], items["C2"]["score"], "override" in items["C2"]) == (7, 0, False)
    # The same form from the course's instructor is taken: the refusals above are the role's, not the form's.
    made = api.client.post(f"/submissions/{sid}/overrides", data=form, headers=api.as_("prof"),
                           follow_redirects=False)
    assert made.status_code == 303 and override_rows(sid) == 1


# --- overrides: the one rule (grader.core.overrides) ----------------------------------------------------------------

def test_an_overridden_inconclusive_item_counts_its_full_points(api):
    """An inconclusive item is stored with max_score 0; overridden, it counts its points, so the total never
    exceeds the maximum."""
    aid = create(api).json()["id"]
    sid = graded(aid, checkpoint_report({"C5": "inconclusive"}))
    before, _ = grade_items(api, sid, "prof")
    assert (before["total"], before["max_total"]) == (7, 7)
    made = api.client.post(f"/v1/submissions/{sid}/overrides", json={"item_id": "C5", "score": 1, "comment": COMMENT},
                           headers=api.as_("prof"))
    assert made.status_code == 201, made.text
    for who in ("prof", "alice"):
        grade, items = grade_items(api, sid, who)
        assert (items["C5"]["score"], items["C5"]["max_score"], items["C5"]["verdict"]) == (1, 1, "inconclusive")
        assert items["C5"]["measured_max_score"] == 0
        assert (grade["total"], grade["max_total"]) == (8, 8), who
        assert all(i["score"] <= i["max_score"] for i in items.values())


def test_an_override_counts_at_most_the_points_a_newer_version_gives_its_item(api):
    """Overrides stay in force when a submission is graded again (a regrade, a re-sent run); where a newer rubric
    version lowered the item's points, the override counts at most those."""
    from grader.core.overrides import current_overrides, overridden_report

    aid = create(api).json()["id"]
    sid = graded(aid, checkpoint_report({"C2": "no_credit"}))
    made = api.client.post(f"/v1/submissions/{sid}/overrides", json={"item_id": "C2", "score": 1, "comment": COMMENT},
                           headers=api.as_("prof"))
    assert made.status_code == 201, made.text
    lowered = checkpoint_report({"C2": "no_credit"}, points={"C2": 0.5}).model_dump(mode="json")
    with _session() as session:
        report = overridden_report(lowered, current_overrides(session, sid))
    c2 = {i["id"]: i for i in report["items"]}["C2"]
    assert (c2["score"], c2["max_score"], c2["override"]["score"], c2["measured_score"]) == (0.5, 0.5, 0.5, 0)
    assert (report["total"], report["max_total"]) == (7.5, 7.5)


# --- what a student sees of a withheld item -------------------------------------------------------------------------

@pytest.mark.parametrize("verdict", ["credit", "no_credit", "inconclusive"])
def test_a_withheld_item_pends_its_points_whatever_its_verdict(api, verdict):
    """A withheld item's worth is its points: counting its max_score instead told the student an inconclusive one
    (max 0) apart from the others before it was shown."""
    aid = create(api, item_visibility={"C5": "on_release"}).json()["id"]
    sid = graded(aid, checkpoint_report({"C5": verdict}))
    grade, items = grade_items(api, sid, "alice")
    assert (items["C5"]["score"], items["C5"]["max_score"], items["C5"]["verdict"]) == (None, 1, "pending")
    assert grade["pending"].startswith("1 of 8 points pending (C5)"), grade["pending"]
    assert (grade["total"], grade["max_total"]) == (7, 8)
    assert api.client.post(f"/v1/assignments/{aid}/release", headers=api.as_("prof")).status_code == 200
    grade, items = grade_items(api, sid, "alice")
    assert items["C5"]["verdict"] == verdict and grade.get("pending") is None


# --- the per-student cap on waiting runs ----------------------------------------------------------------------------

def test_a_students_running_runs_count_against_the_cap(api, monkeypatch):
    from grader.core.models import CaseRun
    from grader.core.settings import settings

    monkeypatch.setattr(settings, "student_waiting_runs_max", 12)
    first = submit_sheet(api)
    assert first.status_code == 202 and len(api.sent) == 9, first.text
    with _session() as session:  # a worker took every run of the first sheet: running, no longer queued
        session.execute(update(CaseRun).where(CaseRun.submission_id == first.json()["id"]).values(status="running"))
        session.commit()
    second = submit_sheet(api)
    assert second.status_code == 409, second.text
    assert "9 of your case runs are still waiting or running" in second.json()["errors"][0]["rule"]
    assert stored() == (1, 9) and len(api.sent) == 9


@pytest.mark.parametrize("limit, accepted", [(18, True), (17, False)])
def test_the_cap_takes_a_sheet_that_reaches_it_exactly_and_refuses_one_past_it(api, monkeypatch, limit, accepted):
    from grader.core.settings import settings

    monkeypatch.setattr(settings, "student_waiting_runs_max", limit)
    assert submit_sheet(api).status_code == 202
    second = submit_sheet(api)  # 9 waiting and 9 more: 18
    assert second.status_code == (202 if accepted else 409), second.text
    assert stored() == ((2, 18) if accepted else (1, 9))


# --- one sign-in link posted twice at once --------------------------------------------------------------------------

def test_one_sign_in_link_posted_twice_at_once_opens_one_session(api, monkeypatch):
    """Both requests read the link unused before either marks it (held there until both have read it): the
    conditional update lets one of them in."""
    from fastapi.testclient import TestClient

    from grader.main import app
    from grader.core.models import WebSession
    from grader.services.identity import sign_in_links

    imported = api.client.post("/v1/courses/l03/roster", json={"csv": ROSTER, "links": True}, headers=api.as_("prof"))
    assert imported.status_code == 200, imported.text
    link = {e["student"]: e for e in imported.json()}["s1001"]["sign_in_link"]
    path = "/sign-in/link/" + link.rsplit("/", 1)[1]
    both_read = threading.Barrier(2, timeout=20)
    calls, real = itertools.count(), sign_in_links.refusal

    def refusal_once_both_have_read(*args, **kwargs):
        why = real(*args, **kwargs)
        if next(calls) < 2:  # the two requests' first checks; the loser's second look passes straight on
            both_read.wait()
        return why

    monkeypatch.setattr(sign_in_links, "refusal", refusal_once_both_have_read)
    answers: list[int] = []
    with TestClient(app) as client:
        def use() -> None:
            answers.append(client.post(path, follow_redirects=False).status_code)

        threads = [threading.Thread(target=use, daemon=True) for _ in range(2)]
        for t in threads:
            t.start()
        for t in threads:
            t.join(60)
    assert sorted(answers) == [303, 410], answers
    with _session() as session:
        assert session.scalar(select(func.count()).select_from(WebSession)) == 1


# --- LTI launches -----------------------------------------------------------------------------------------------------

def test_a_launch_after_its_logins_lifetime_is_refused(api, platform):
    from grader.core.models import LtiLaunchState, utcnow

    fields = launch_form(api, platform, "lms-user-17")
    with _session() as session:  # the login's state outlived (the platform's id_token itself is still valid)
        session.execute(update(LtiLaunchState).where(LtiLaunchState.state == fields["state"])
                        .values(expires_at=utcnow() - timedelta(seconds=1)))
        session.commit()
    _refused(api, post_launch(api, fields), "id_token.nonce")
    from tests.grader.services.lti.test_lti import counts

    assert counts()["lti_identities"] == 0


def test_a_nonce_issued_for_another_login_is_refused(api, platform):
    """Two logins in one browser: the first login's id_token posted with the second login's state (its cookie is
    there) carries a nonce this tool sent with another state."""
    from tests.grader.services.lti.test_lti import counts

    first = launch_form(api, platform, "lms-user-17")
    second = launch_form(api, platform, "lms-user-17")
    assert first["state"] != second["state"]
    before = counts()
    _refused(api, post_launch(api, {"id_token": first["id_token"], "state": second["state"]}), "id_token.nonce")
    assert counts() == before
    assert post_launch(api, second).status_code == 200  # each login's own launch is taken


# --- scores to the LMS ------------------------------------------------------------------------------------------------

def test_a_new_attempt_with_the_same_score_is_sent_with_its_own_link(api, platform):
    """The gradebook's comment names the counted attempt's report: a new attempt scoring the same is news."""
    platform.tool_jwks = api.client.get("/lti/jwks").json()
    aid = create(api).json()["id"]
    assert post_launch(api, launch_form(api, platform, "lms-user-17")).status_code == 200
    graded_attempt(aid, "lms-user-17", 1, 7.0)
    assert [s["status"] for s in send(api, aid)] == ["sent"]
    second = graded_attempt(aid, "lms-user-17", 2, 7.0)
    assert [(s["status"], s["score"]) for s in send(api, aid)] == [("sent", 7.0)]
    score = platform.line_items[0]["scores"]["lms-user-17"]
    assert score["comment"] == f"attempt 2: http://testserver/submissions/{second}"
    assert [s["status"] for s in send(api, aid)] == ["unchanged"]


def test_a_grade_stored_while_sends_back_off_keeps_the_retry_time(api, platform):
    aid = launched(api, platform)
    platform.refuse_scores = True
    outbox_grade(aid, 1, 6.0)
    (failed,) = sweep()
    assert failed.error and failed.next_try_at is not None
    outbox_grade(aid, 2, 8.0)  # a new grade during the back-off marks the assignment again
    assert outbox(aid).due_at == failed.next_try_at
    assert sweep() == []  # the platform that is down is not asked again before its retry time
    platform.refuse_scores = False
    (retried,) = sweep(now=failed.next_try_at + timedelta(seconds=1))
    assert retried.counts == {"sent": 1}
    assert platform.line_items[0]["scores"]["lms-user-17"]["scoreGiven"] == 8.0
