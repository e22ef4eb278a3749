"""A submission's progress (grader.services.submissions.progress, grader.pages.submissions.progress) on the in-process app: each waiting
run's place in its queue counted from the database in the order the senders' priorities serve it, the estimate from
the medians of measured runs of the same case, the page and the JSON its script polls, and who may see them."""

from __future__ import annotations

import re
from datetime import timedelta

import pytest
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


@pytest.fixture
def pg_api(tmp_path, monkeypatch):
    """The app in-process on a fresh PostgreSQL database (READ COMMITTED by default: a snapshot per statement)."""
    from tests import services
    from tests.grader.conftest import app_on

    with services.postgres_database() as url, app_on(url, tmp_path, monkeypatch) as state:
        yield state


@pytest.mark.parametrize("backend", ["sqlite", pytest.param("postgresql", marks=pytest.mark.integration)])
def test_the_first_render_shows_each_queued_runs_place_though_a_worker_claims_one_between_the_reads(
        backend, request, monkeypatch):
    """Issue 49: the first render showed a run "queued" with place "-" and no queue section while the database had it
    queued: the page read the runs' states, a worker claimed one, then the queue order was read without it. Here a
    worker's claim (grader.core.lifecycle.claim, committed from its own connection) lands between the two reads of
    every render; the states and the places must come from one moment: a run shown queued has its place, and the
    places count the runs shown queued (the moment before the claim or after it, either is true)."""
    from grader.core.lifecycle import claim

    api = request.getfixturevalue("api" if backend == "sqlite" else "pg_api")
    mine = submit(api, "alice")
    claimed: list[int] = []
    original = progress.queue_order

    def claimed_between_the_reads(session, backend_name):
        with new_session() as worker:  # a worker's connection, committing while the page reads
            run_id = worker.scalar(select(CaseRun.id).where(CaseRun.submission_id == mine,
                                                            CaseRun.status == CaseRunState.QUEUED)
                                   .order_by(CaseRun.id))
            run, _ = claim(session=worker, case_run_id=run_id, delivery=1)
            assert run is not None
            worker.commit()
            claimed.append(run_id)
        return original(session, backend_name)

    monkeypatch.setattr(progress, "queue_order", claimed_between_the_reads)
    page = api.client.get(f"/submissions/{mine}/progress", headers=api.as_("alice"))
    assert page.status_code == 200 and len(claimed) == 1, page.text
    shown = {name: (state, place.strip()) for name, state, place in re.findall(
        r'<tr id="run-([^"]+)">.*?data-state="(\w+)".*?<td data-label="place in queue">(.*?)</td>', page.text, re.S)}
    queued = [name for name, (state, _) in shown.items() if state == "queued"]
    assert len(shown) == 9 and queued, shown
    assert sorted(place for state, place in shown.values() if state == "queued") == \
        sorted(f"{k} of {len(queued)}" for k in range(1, len(queued) + 1)), shown
    assert all(place == "–" or place.startswith("being run") for state, place in shown.values() if state != "queued")
    assert 'id="queue-place"' in page.text
    # The JSON the script polls, read the same way (another claim between its reads).
    data = api.client.get(f"/submissions/{mine}/progress.json", headers=api.as_("alice")).json()
    assert len(claimed) == 2
    waiting = [r for r in data["runs"] if r["status"] == "queued"]
    assert sorted(r["position"] for r in waiting) == list(range(1, len(waiting) + 1)), data["runs"]
    assert all(r["waiting"] == len(waiting) for r in waiting)
    assert all(r["position"] is None for r in data["runs"] if r["status"] != "queued")
    with new_session() as session:  # the claims were committed: the database moved on while each render read
        assert {r.id for r in runs_of(session, mine) if r.status == CaseRunState.RUNNING} == set(claimed)


def _runs(submission_id: int) -> list[CaseRun]:
    with new_session() as session:
        return runs_of(session, submission_id)


def _user(session, name: str):
    from grader.core.models import User

    return session.scalar(select(User).where(User.name == name))


WARM = {"execution_mode": "warm", "scene": "reused"}  # what a warm case process records for a case on a kept scene


def measure(run: CaseRun, wall_s: float, provenance: dict | None = None, *, ago_s: float = 0.0) -> None:
    """As a worker leaves a run that measured its case: done, ok, its time and the provenance's execution mode."""
    run.status, run.result_status, run.wall_s = "done", "ok", wall_s
    run.provenance = dict(WARM if provenance is None else provenance)
    run.finished_at = utcnow() - timedelta(seconds=ago_s)
    run.started_at = run.finished_at - timedelta(seconds=wall_s)


def test_the_estimate_is_the_median_and_range_of_warm_runs_of_the_same_case_warm_up_left_out(api):
    earlier = [submit(api, "prof") for _ in range(6)]
    bob, mine = submit(api, "bob"), submit(api, "alice")
    with new_session() as session:
        # N1 of earlier submissions: three warm runs on kept scenes (1, 3, 8 s); a first scene build (the warm-up,
        # 30 s), an isolated run (14 s) and a failed one (100 s) are not what a warm worker takes for it.
        for sid, (wall, provenance, status) in zip(earlier, [
                (1.0, WARM, "ok"), (3.0, WARM, "ok"), (8.0, WARM, "ok"),
                (30.0, {"execution_mode": "warm", "scene": "fresh"}, "ok"),
                (14.0, {"execution_mode": "isolated"}, "ok"), (100.0, WARM, "error")]):
            run = next(r for r in runs_of(session, sid) if r.name == "N1")
            measure(run, wall, provenance)
            run.result_status = status
        # N2 once, but reused from a stored measurement: no time of its own.
        reused = next(r for r in runs_of(session, earlier[0]) if r.name == "N2")
        measure(reused, 0.0)
        reused.reused_from_id = runs_of(session, earlier[1])[0].id
        session.commit()
        p = progress.submission_progress(session=session, user=_user(session, "alice"), submission_id=mine)
    by_name = {r.name: r for r in p.runs}
    n1 = by_name["N1"].estimate
    assert (n1.median_s, n1.low_s, n1.high_s, n1.runs, n1.basis) == (3.0, 1.0, 8.0, 3, "case")
    # N2 was never measured itself: estimated from the contact runs measured on cpu (N1's three).
    n2 = by_name["N2"].estimate
    assert (n2.median_s, n2.low_s, n2.high_s, n2.runs, n2.basis) == (3.0, 1.0, 8.0, 3, "kind")
    # No friction case was measured: its time is not known, and no total is claimed.
    assert by_name["friction-baseline"].estimate is None and p.own_s is None
    # Ahead of her first run (N1): Bob's N1, sent at the same best priority before hers; the prof's wait behind.
    assert by_name["N1"].position == 2 and p.ahead_s == 3.0 and p.ahead_unmeasured == 0
    assert p.phase == "waiting" and bob
    page = api.client.get(f"/submissions/{mine}/progress", headers=api.as_("alice"))
    assert page.status_code == 200, page.text
    row = page.text.split('id="run-N1"', 1)[1].split("</tr>", 1)[0]
    assert "about 3.0 s" in row and "median of 3 measured runs of this case, 1.0 s–8.0 s" in row
    row = page.text.split('id="run-N2"', 1)[1].split("</tr>", 1)[0]
    assert "never measured: median of 3 measured contact runs, 1.0 s–8.0 s" in row
    assert "not known: nothing of its kind measured yet" in page.text.split('id="run-friction-baseline"', 1)[1]
    assert re.search(r"Your first waiting case run is number 2 of \d+ queued on the cpu queue: 1 run waits ahead of it\.",
                     page.text)
    assert "Case time ahead of it, from measured durations: about 3.0 s." in page.text
    assert "Running your cases" not in page.text and "wait in the queue: none is being run yet" in page.text


def test_a_run_being_run_ahead_is_counted_with_its_time_left_and_a_queued_run_is_not_called_running(api):
    earlier = submit(api, "prof")
    bob, mine = submit(api, "bob"), submit(api, "alice")
    with new_session() as session:
        for run in runs_of(session, earlier):  # every case measured warm: contact 2 s, friction 4 s
            measure(run, 2.0 if run.kind == "contact" else 4.0)
        # Bob's N1 is being run, 0.5 s in, his other runs done; Alice's N1 is done (reused), the rest of hers wait.
        bobs, *others = runs_of(session, bob)
        for run in others:
            measure(run, 0.0)
            run.reused_from_id = runs_of(session, earlier)[0].id
        bobs.status, bobs.started_at = CaseRunState.RUNNING, utcnow() - timedelta(seconds=0.5)
        hers = runs_of(session, mine)
        measure(hers[0], 0.0)
        hers[0].reused_from_id = runs_of(session, earlier)[0].id
        session.commit()
        p = progress.submission_progress(session=session, user=_user(session, "alice"), submission_id=mine)
        first = min((r for r in p.runs if r.position), key=lambda r: r.position)
    assert p.phase == "waiting" and p.counts == {"queued": 8, "running": 0, "done": 1, "failed": 0}
    (ahead,) = p.running_ahead
    # its time left: the estimate less the time it has run (measured when the page was read; the machine may be slow)
    assert ahead.kind == "contact" and ahead.estimate.median_s == 2.0 and ahead.running_s >= 0.5
    assert ahead.remaining_s == max(0.0, 2.0 - ahead.running_s) and ahead.remaining_s <= 1.5
    # next in the queue, yet a run is ahead of it: its time left counted (unknown once it ran past its estimate)
    assert first.position == 1 and p.ahead_s == (0.0 if ahead.overdue else ahead.remaining_s)
    assert p.own_s == sum(r.estimate.median_s for r in p.runs if not r.finished)
    page = api.client.get(f"/submissions/{mine}/progress", headers=api.as_("alice")).text
    assert "Nothing" not in page.split('id="estimate"', 1)[1].split("</p>", 1)[0]
    assert re.search(r"a contact case on cpu, running for \d+\.\d s:\s+(about \d+\.\d s left|longer than its "
                     r"estimate of 2\.0 s)", page)
    assert "Your first waiting case run is next of" in page
    data = api.client.get(f"/submissions/{mine}/progress.json", headers=api.as_("alice")).json()
    assert data["phase"] == "waiting" and data["running_ahead"][0]["estimate"]["median_s"] == 2.0
    # Her own run starts: now she is running, with its time left counted in her own.
    with new_session() as session:
        run = session.get(CaseRun, first.id)
        run.status, run.started_at = CaseRunState.RUNNING, utcnow() - timedelta(seconds=1)
        session.commit()
        p = progress.submission_progress(session=session, user=_user(session, "alice"), submission_id=mine)
    assert p.phase == "running"
    mine_running = next(r for r in p.runs if r.id == first.id)
    assert mine_running.running_s >= 1.0
    assert mine_running.remaining_s == max(0.0, mine_running.estimate.median_s - mine_running.running_s)
    page = api.client.get(f"/submissions/{mine}/progress", headers=api.as_("alice")).text
    assert "1 of your case runs is being run now." in page
    row = page.split(f'id="run-{mine_running.name}"', 1)[1].split("</tr>", 1)[0]
    assert 'data-state="running"' in row and re.search(r"being run, for \d+\.\d s", row)
    assert "left" in row or "longer than its estimate" in row


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


def test_a_config_never_measured_is_estimated_from_its_size_within_a_factor_of_two_of_its_measured_time(
        api, measured, lesson_measured):
    """Issue 49: a config never measured was estimated from the median of its kind's runs, whatever its size (a
    37,500-update config said "about 0.3 s left" and took 120 s). Now from its internal updates at the time per update
    of its kind's measured runs, on real Genesis times: the lesson's contact runs N1-N4 are stored (lesson_measured),
    alice's sheet asks for its extension (the lesson's N5 physics: dt 0.01 s at 4 substeps, 600 internal updates, 4x
    N1's), which nothing stored measured; its estimate is within a factor of 2 of what N5 took, measured in the same
    warm process as N1-N4, and the page says what it rests on."""
    mine = submit(api, "alice")
    with new_session() as session:
        p = progress.submission_progress(session=session, user=_user(session, "alice"), submission_id=mine)
    extension = next(r for r in p.runs if r.name == "sheet.extension")
    estimate = extension.estimate
    assert estimate is not None and estimate.basis == "size" and estimate.updates == 600, estimate
    took = measured["N5"].wall_s
    assert took / 2 <= estimate.median_s <= took * 2, (estimate, took, {n: measured[n].wall_s for n in measured})
    assert estimate.low_s <= estimate.median_s <= estimate.high_s and estimate.runs >= 1
    page = api.client.get(f"/submissions/{mine}/progress", headers=api.as_("alice")).text
    row = page.split('id="run-sheet.extension"', 1)[1].split("</tr>", 1)[0]
    assert "never measured: its 600 internal updates at the" in row and "time per update of" in row, row
    assert progress.as_json(p)["runs"][[r.name for r in p.runs].index("sheet.extension")]["estimate"]["updates"] == 600
