"""The class dashboard's new parts in a real browser over the real stack (API over HTTP, a Celery worker on Redis,
PostgreSQL, real Genesis runs): predictions against measurements and the per-backend spread equal the JSON, the
charts load and are the course staff's only, and a failed and a stuck case run are re-sent from the dashboard and
the submission is graded. Screenshots land in out/screenshots/ (or $SCREENSHOTS_DIR)."""

from __future__ import annotations

import subprocess
import sys
from datetime import timedelta

import pytest
from sqlalchemy import select
from sqlalchemy.orm import Session

from grader.core.models import CaseRun, Course, Submission, utcnow
from rubric import load_rubric
from tests import services
from tests.factories import reference_sheet
from tests.integration.helpers import (SHOTS, WAIT_LIMIT_S, case_runs, events, grades_of, images_decoded, signed_in,
                                       wait_until)
from tests.integration.layout import pages_in_both_languages

pytestmark = [pytest.mark.integration, pytest.mark.slow]
COURSE = "l03-test"


def _fmt(value, spec: str, missing: str = "–") -> str:
    return missing if value is None else format(value, spec)


def _course_runs(stack) -> list[CaseRun]:
    with Session(stack.engine) as session:
        return session.scalars(select(CaseRun).join(Submission).join(Course).where(Course.name == COURSE)).all()


def test_predictions_and_measurements_by_backend_equal_the_json_and_the_charts_load(browser, stack, graded):
    data = stack.client("prof").dashboard(COURSE)
    plots = {p["item"]: p for p in data["predictions"]}
    assert list(plots) == ["H1", "H4"]
    # The graded class's latest attempts: Alice's and Bob's, four numbers each per item.
    h4 = {(r["student"], r["run"], r["lane"]): r for r in plots["H4"]["rows"]}
    assert {s for s, _, _ in h4} >= {"alice", "bob"} and plots["H4"]["tolerances"] == [0.02]
    # The reference sheet writes centimetres; the dashboard compares metres, with what the engine measured.
    alice = h4[("alice", "baseline", "low")]
    assert alice["predicted_as_written"] == "41 cm" and alice["predicted"] == pytest.approx(0.41)
    baseline = next(r for r in stack.client("alice").case_runs(graded["alice"]["id"])
                    if r["name"] == "friction-baseline")
    for lane in ("low", "high"):
        stop = baseline["metrics"]["lanes"][lane]["stop"]
        assert h4[("alice", "baseline", lane)]["measured"] == (stop["distance"] if stop["stopped"] else None)
        assert h4[("alice", "baseline", lane)]["backend"] == baseline["actual_backend"] == "cpu"
    h1 = {(r["student"], r["run"], r["lane"]): r for r in plots["H1"]["rows"]}
    assert h1[("alice", "modified", "low")]["measured"] == pytest.approx(0.3, abs=1e-6)

    page = signed_in(browser, stack, "prof")
    page.click("text=Class dashboard")
    page.wait_for_selector("#predictions")
    for item, plot in plots.items():
        table = page.locator(f"#predictions-{item}")
        headers = [h.strip() for h in table.locator("thead th").all_inner_texts()]
        assert headers[:5] == ["student", "submission", "run", "lane", "predicted (as written)"], headers
        rows = table.locator("tbody tr")
        assert rows.count() == len(plot["rows"])
        for i, r in enumerate(plot["rows"]):
            cells = [c.strip() for c in rows.nth(i).locator("td").all_inner_texts()]
            within = {True: "yes", False: "no", None: "–"}[r["within_tolerance"]]
            assert cells == [r["student"], str(r["submission_id"]), r["run"], r["lane"], r["predicted_as_written"],
                             _fmt(r["predicted"], ".4g"), _fmt(r["measured"], ".4g", r["measured_text"]),
                             _fmt(r["difference"], "+.3g"), within, f"{r['case']} on {r['backend'] or '–'}"], (item, i)
    spread = data["backends"]["groups"]
    rows = page.locator("#backends tbody tr")
    assert rows.count() == len(spread)
    for i, g in enumerate(spread):
        cells = [c.strip() for c in rows.nth(i).locator("td").all_inner_texts()]
        assert cells[1:6] == [g["case"], g["lane"] or "–", g["backend"], str(g["n"]), str(g["not_stopped"])]
        assert cells[6:] == [_fmt(v, ".5f") for v in (g["min"], g["median"], g["max"])]
    # A measurement reused by several runs counts once: N1's count is the course's distinct N1 measurements.
    n1_runs = [r for r in _course_runs(stack) if r.name == "N1" and r.status == "done" and r.actual_backend == "cpu"]
    n1 = next(g for g in spread if (g["case"], g["backend"]) == ("N1", "cpu"))
    distinct = {r.measurement_id or -r.id: r.metrics["penetration_proxy"] for r in n1_runs}
    assert n1["n"] == len(distinct) < len(n1_runs)
    assert n1["values"] == sorted(distinct.values())

    charts = [p["chart"] for p in plots.values()] + [data["backends"]["chart"]]
    assert sorted(page.locator("figure.chart img").evaluate_all("els => els.map(e => e.getAttribute('src'))")) \
        == sorted(charts)
    images_decoded(page, "figure.chart img")  # every chart decoded, none broken
    page.locator("#predictions").scroll_into_view_if_needed()
    page.screenshot(path=SHOTS / "instructor_dashboard_predictions.png", full_page=True)

    # Score distributions of like with like: one per assignment and one per maximum outside assignments, each with
    # its own "of MAX"; never an 8-point checkpoint attempt in a 30-point sheet's bins.
    groups = data["score_groups"]
    assert groups and all(g["distribution"][-1]["high"] == g["max_total"] for g in groups)
    assert len({(g["assignment_id"], g["max_total"]) for g in groups}) == len(groups)
    free = [g for g in groups if g["assignment_id"] is None]
    assert [g["max_total"] for g in free] == sorted({g["max_total"] for g in free})
    for g in groups:
        key = g["assignment_id"] or f"free-{g['max_total']:g}"
        assert page.locator(f"#distribution-{key} tbody tr").count() == len(g["distribution"])
        summary = page.locator(f"#distribution-{key}").locator("xpath=preceding-sibling::p[1]").inner_text()
        assert summary.endswith(f"of {g['max_total']:g}") and summary.startswith(f"{g['n']} student"), summary
    # the per-day counts are the course's calendar days, and the heading says which zone
    zone = stack.client("prof").course(COURSE)["timezone"]
    assert page.locator(f"h2:text-is('Submissions per day ({zone})')").count() == 1
    pages_in_both_languages(browser, lambda b, **kw: _signed_in(b, stack, "prof", **kw),
                            f"{stack.url}/courses/{COURSE}/dashboard", SHOTS, "dashboard", ready="#what-changed",
                            fits=False)

    student = signed_in(browser, stack, "alice")
    for url in charts:
        assert student.request.get(f"{stack.url}{url}").status == 404, url
        assert page.request.get(f"{stack.url}{url}").status == 200, url


def _signed_in(browser, stack, who: str, *, locale: str = "en", width: int = 1280):
    page = browser.new_page(viewport={"width": width, "height": 900}, locale=locale)
    page.goto(f"{stack.url}/submissions")
    page.fill("#token", stack.tokens[who])
    page.click("form[action='/sign-in'] button[type=submit]")
    page.wait_for_selector("header .who")
    return page


def _student(stack, name: str) -> tuple[int, str]:
    """A third student of the course (the shared graded class stays as the page tests expect), with a token."""
    from grader.services.identity import accounts

    with Session(stack.engine) as session:
        course = session.scalar(select(Course).where(Course.name == COURSE))
        user = accounts.get_or_create_user(session=session, course=course, name=name, role="student")
        token = accounts.create_token(session=session, user=user)
        session.commit()
        return user.id, token


def test_a_failed_and_a_stuck_run_are_resent_from_the_dashboard_and_graded(browser, stack, graded):
    """Carol's submission lost deliveries to dead workers: one case run used up its deliveries (the real worker
    fails it when its last message arrives), another is held by a worker that died (a dead lease, no message)."""
    from grader.services.submissions import sheets, submit as submissions
    from grader.client import Client
    from grader.core.models import User
    from grader.core.settings import settings

    user_id, token = _student(stack, "carol")
    carol = Client(stack.url, token)
    sheet = reference_sheet() | {"student": "carol"}
    with Session(stack.engine) as session:
        user = session.get(User, user_id)  # this course's Carol, not test_regrade's of another course
        submission = submissions.create_submission(session=session, student=user, lesson="L03", sheet=sheet,
                                            specs=sheets.cases_to_run(sheets.parse_sheet(sheet), load_rubric("L03")), force_rerun=False)
        session.flush()
        runs = {r.name: r for r in submission.case_runs}
        lost = utcnow() - timedelta(hours=1)
        for name, tries in (("N3", settings.max_infra_retries + 1), ("N4", 1)):
            runs[name].status, runs[name].worker, runs[name].worker_pid = "running", "lost-host", 1
            runs[name].tries, runs[name].lease_until = tries, lost
        session.commit()
        submission_id = submission.id
        failing, stuck = runs["N3"].id, runs["N4"].id
        to_send = [(r.id, r.delivery, r.backend) for name, r in runs.items() if name != "N4"]
    # Every run but the stuck one is delivered to the real worker (N3's message is its last redelivery).
    send = "; ".join(f"dispatch.send_case_run({i}, {a}, {b!r})" for i, a, b in to_send)
    done = subprocess.run([sys.executable, "-c", f"from grader import dispatch; {send}"], env=stack.env,
                          cwd=services.ROOT, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr

    def settled():
        states = {r.name: r.status for r in case_runs(stack, submission_id)}
        return states if states["N3"] == "failed" and sum(s == "done" for s in states.values()) == len(states) - 2 \
            else None

    wait_until(settled, "every run but N3 (failed) and N4 (stuck) done", WAIT_LIMIT_S)
    assert carol.submission(submission_id)["status"] == "running"
    problems = {p["case_run_id"]: p for p in stack.client("prof").dashboard(COURSE)["problems"]
                if p["submission_id"] == submission_id}
    assert set(problems) == {failing, stuck}
    assert "gave up after" in problems[failing]["reason"] and problems[failing]["status"] == "failed"
    assert "past its lease" in problems[stuck]["reason"] and problems[stuck]["status"] == "running"
    assert all(p["resendable"] for p in problems.values())

    page = signed_in(browser, stack, "prof")
    page.goto(f"{stack.url}/courses/{COURSE}/dashboard#problems")
    for run_id in (failing, stuck):
        assert page.locator(f"#problem-{run_id} button.resend").count() == 1
    page.locator("#problems-section").scroll_into_view_if_needed()
    page.screenshot(path=SHOTS / "instructor_dashboard_resend.png", full_page=False)
    student = browser.new_page()  # Carol signs in: her post is refused, and nothing changes
    student.goto(f"{stack.url}/sign-in")
    student.fill("#token", token)
    student.click("form[action='/sign-in'] button[type=submit]")  # not the header's language buttons
    student.wait_for_url(f"{stack.url}/submissions")
    refused = student.request.post(f"{stack.url}/courses/{COURSE}/dashboard/case-runs/{failing}/resend")
    assert refused.status == 404
    assert {r.id: r.status for r in case_runs(stack, submission_id)}[failing] == "failed"

    page.click(f"#problem-{failing} button.resend")
    page.wait_for_selector("p.notice-ok")
    assert f"Case run {failing} (N3 of submission {submission_id}) was re-sent" in page.inner_text("p.notice-ok")
    page.click(f"#problem-{stuck} button.resend")
    page.wait_for_selector(f"p.notice-ok:has-text('Case run {stuck} (N4 of submission {submission_id})')")
    final = carol.wait(submission_id, poll_s=0.5, timeout_s=WAIT_LIMIT_S)
    assert final["status"] == "graded", final
    after = {r.id: r for r in case_runs(stack, submission_id)}
    assert after[failing].status == after[stuck].status == "done"
    assert after[failing].delivery == after[stuck].delivery == 2 and after[failing].error is None
    grade = carol.grade(submission_id)
    assert not [i["id"] for i in grade["items"] if i["verdict"] == "not_measured"]  # N3 and N4 measured
    assert grades_of(stack, submission_id) == 1
    log = events(stack, submission_id)
    resent = {e.case_run_id: e.detail for e in log if e.state == "resent"}
    assert set(resent) == {failing, stuck} and all("by instructor prof" in d for d in resent.values())
    assert "gave up after" in resent[failing] and "past its lease" in resent[stuck]
    states = [e.state for e in log if e.case_run_id == failing]
    assert states[-4:] == ["failed", "resent", "running", "done"], states  # the old failure stays in the log
    assert [e.state for e in log].count("graded") == 1
    page.goto(f"{stack.url}/courses/{COURSE}/dashboard")
    assert page.locator(f"#problem-{failing}").count() == page.locator(f"#problem-{stuck}").count() == 0
    again = page.request.post(f"{stack.url}/v1/case-runs/{failing}/resend",
                              headers={"Authorization": f"Bearer {stack.tokens['prof']}"})
    assert again.status == 409 and "neither failed nor stuck" in again.json()["detail"]
