"""A submission's progress (grader.services.submissions.progress, grader.pages.submissions.progress) on the in-process app: each waiting
run's place in its queue counted from the database in the order the senders' priorities serve it, the estimate from
the medians of measured runs of the same case, the page and the JSON its script polls, and who may see them."""

from __future__ import annotations

import re

from sqlalchemy import select

from grader.core.db import new_session
from grader.core.states import CaseRunState
from grader.core.models import CaseRun, Submission, utcnow
from grader.services.submissions import progress
from tests.factories import reference_sheet


def submit(api, who: str) -> int:
    created = api.client.post("/v1/submissions", headers=api.as_(who),
                              json={"sheet": reference_sheet() | {"student": who}})
    assert created.status_code == 202, created.text
    return created.json()["id"]


def runs_of(session, submission_id: int) -> list[CaseRun]:
    return list(session.scalars(select(CaseRun).where(CaseRun.submission_id == submission_id).order_by(CaseRun.id)))


def finish(session, runs: list[CaseRun], wall_s: float = 1.0) -> None:
    """As a worker leaves them: started, then done with a measured time."""
    for run in runs:
        run.status, run.result_status, run.wall_s = CaseRunState.DONE, "ok", wall_s
        run.started_at = run.finished_at = utcnow()
    session.commit()


def test_the_queue_order_counted_from_the_database_is_the_order_the_sent_priorities_serve(api):
    alice = submit(api, "alice")
    with new_session() as session:  # three of her runs are done before the others submit
        finish(session, runs_of(session, alice)[:3])
    bob, again = submit(api, "bob"), submit(api, "alice")
    queued = {args[0] for args in api.sent} - {r.id for r in _runs(alice)[:3]}
    sent = [(priority, i, args[0]) for i, (args, priority) in enumerate(zip(api.sent, api.priorities))
            if args[0] in queued]
    assert len(sent) == 24 and len(set(api.priorities)) > 1  # the fair priorities interleave the students
    served = [run_id for _, _, run_id in sorted(sent)]  # a broker draws the lowest priority first, then in order
    with new_session() as session:
        assert progress.queue_order(session, "cpu") == served
        bobs = progress.submission_progress(session=session, user=_user(session, "bob"), submission_id=bob)
    # Bob's first run is sent at the best fair priority: only Alice's first run of that priority, long done, was.
    assert bobs.runs[0].position == 1 and all(r.waiting == 24 for r in bobs.runs)
    assert bobs.status == "running" and not bobs.finished and bobs.counts["queued"] == 9
    # A run being run leaves the queue: everyone behind it moves up one place.
    with new_session() as session:
        runs_of(session, bob)[0].status = CaseRunState.RUNNING
        session.commit()
        bobs = progress.submission_progress(session=session, user=_user(session, "bob"), submission_id=bob)
        assert bobs.runs[0].position is None and bobs.runs[1].position == served.index(bobs.runs[1].id)
        assert bobs.runs[1].waiting == 23 and bobs.running_on_backend == {"cpu": 1}
    assert again


def _runs(submission_id: int) -> list[CaseRun]:
    with new_session() as session:
        return runs_of(session, submission_id)


def _user(session, name: str):
    from grader.core.models import User

    return session.scalar(select(User).where(User.name == name))


def test_the_estimate_is_the_median_of_real_runs_of_the_same_case_and_says_when_there_is_none(api):
    earlier = [submit(api, "prof") for _ in range(4)]
    bob, mine = submit(api, "bob"), submit(api, "alice")
    with new_session() as session:
        # N1 of earlier submissions: three real runs (1, 3, 8 s), one reused (no time of its own), one failed.
        for sid, (status, result, wall, reused) in zip(earlier, [
                ("done", "ok", 1.0, False), ("done", "ok", 3.0, False), ("done", "ok", 8.0, False),
                ("failed", "error", 100.0, False)]):
            run = next(r for r in runs_of(session, sid) if r.name == "N1")
            run.status, run.result_status, run.wall_s = status, result, wall
            run.started_at = run.finished_at = utcnow()
        reused = next(r for r in runs_of(session, earlier[0]) if r.name == "N2")
        reused.status, reused.result_status, reused.reused_from_id = "done", "ok", runs_of(session, earlier[1])[0].id
        reused.started_at = reused.finished_at = utcnow()
        session.commit()
        p = progress.submission_progress(session=session, user=_user(session, "alice"), submission_id=mine)
    by_name = {r.name: r for r in p.runs}
    assert (by_name["N1"].typical_s, by_name["N1"].measured_runs) == (3.0, 3)
    assert (by_name["N2"].typical_s, by_name["N2"].measured_runs) == (None, 0)
    assert p.own_s is None  # one of her cases was never measured: no total is claimed
    # Ahead of her first run (N1): Bob's N1, sent at the same best priority before hers; the prof's wait behind.
    assert by_name["N1"].position == 2 and p.ahead_s == 3.0 and p.ahead_unmeasured == 0
    assert bob
    page = api.client.get(f"/submissions/{mine}/progress", headers=api.as_("alice"))
    assert page.status_code == 200, page.text
    row = page.text.split('id="run-N1"', 1)[1].split("</tr>", 1)[0]
    assert "3.0 s" in row and "(median of 3)" in row
    assert "no measurement yet" in page.text.split('id="run-N2"', 1)[1].split("</tr>", 1)[0]
    assert re.search(r"Your first waiting case run is number \d+ of \d+ queued on the cpu queue", page.text)


def test_the_page_refreshes_without_a_script_and_its_json_carries_the_same_live_part(api):
    sid = submit(api, "alice")
    page = api.client.get(f"/submissions/{sid}/progress", headers=api.as_("alice"))
    assert page.status_code == 200, page.text
    assert '<noscript><meta http-equiv="refresh" content="3"></noscript>' in page.text
    assert '<script src="/static/progress.js" defer></script>' in page.text and "style=" not in page.text
    assert f'data-poll-url="/submissions/{sid}/progress.json"' in page.text
    polled = api.client.get(f"/submissions/{sid}/progress.json", headers=api.as_("alice"))
    assert polled.status_code == 200 and polled.headers["cache-control"] == "no-store"
    data = polled.json()
    assert data["status"] == "running" and data["finished"] is False and len(data["runs"]) == 9
    assert {r["status"] for r in data["runs"]} == {"queued"} and data["runs"][0]["position"] == 1
    assert data["html"].strip() in page.text  # one rendering: the script shows what the page shows
    assert api.client.get("/static/progress.js").status_code == 200
    # Graded: no refresh, and the page leads to the report.
    with new_session() as session:
        session.get(Submission, sid).status = "graded"
        for run in runs_of(session, sid):
            run.status, run.result_status, run.wall_s = "done", "ok", 1.5
        session.commit()
    done = api.client.get(f"/submissions/{sid}/progress", headers=api.as_("alice"))
    assert "http-equiv" not in done.text and 'data-finished="true"' in done.text
    assert f'<a href="/submissions/{sid}" id="report-link">Read the report</a>' in done.text
    assert api.client.get(f"/submissions/{sid}/progress.json", headers=api.as_("alice")).json()["finished"] is True


def test_only_who_may_read_the_submission_sees_its_progress(api):
    sid = submit(api, "alice")
    for who in ("bob", "eve"):  # another student; another course's instructor
        page = api.client.get(f"/submissions/{sid}/progress", headers=api.as_(who))
        assert page.status_code == 404 and "run-N1" not in page.text
        polled = api.client.get(f"/submissions/{sid}/progress.json", headers=api.as_(who))
        assert polled.status_code == 404 and "runs" not in polled.json()
    assert api.client.get(f"/submissions/{sid}/progress", headers=api.as_("prof")).status_code == 200
    assert api.client.get("/submissions/999999/progress.json", headers=api.as_("alice")).status_code == 404
    anonymous = api.client.get(f"/submissions/{sid}/progress", follow_redirects=False)
    assert anonymous.status_code == 303 and anonymous.headers["location"].startswith("/sign-in")
