"""The instructor's assignment page in a real browser (Debian's chromium driven by Playwright) over the API on
loopback with PostgreSQL. The lesson's own cases are stored as really measured (the session's `measured` runs), so
checkpoint sheets are graded in the request on them and no worker is needed. The screenshots land in out/screenshots/
(or $SCREENSHOTS_DIR)."""

from __future__ import annotations

import pytest

from tests.grader.services.setup.test_assignments import checkpoint_sheet
from tests.integration.helpers import SHOTS, at, measured_course_api, signed_in

pytestmark = pytest.mark.integration
COURSE = "l03-assign"


@pytest.fixture(scope="module")
def api(tmp_path_factory, measured):
    """The API alone (uvicorn) on a fresh PostgreSQL database where the lesson's cases were measured; nothing is ever
    enqueued here."""
    with measured_course_api(tmp_path_factory.mktemp("assignment-page"), measured, course=COURSE) as running:
        yield running


def test_the_instructor_opens_an_assignment_from_the_dashboard_and_reads_every_students_grade(browser, api):
    prof = api.client("prof")
    prof.update_course(COURSE, {"timezone": "Europe/Berlin"})
    prof.import_roster(COURSE, "student_id,name,email\ns1001,Ada Lovelace,ada@example.edu\n")
    assignment = prof.create_assignment(COURSE, {
        "title": "Week 3 checkpoints", "part": "checkpoints", "open_at": at(days=-3), "due_at": at(hours=-26),
        "hard_close_at": at(days=2), "late_penalty_per_day": 0.1, "late_penalty_cap": 0.3, "counted_attempt": "best",
        "item_visibility": {"C3": "on_release"}, "max_attempts": 3})
    aid = assignment["id"]
    prof.extend(aid, {"student": "bob", "due_at": at(days=1), "hard_close_at": at(days=2)})
    first = api.client("alice").submit(checkpoint_sheet("alice"), assignment_id=aid)
    worse = checkpoint_sheet("alice")
    worse["answers"]["C2"]["reason"] = "it_is_valid"
    api.client("alice").submit(worse, assignment_id=aid)
    api.client("bob").submit(checkpoint_sheet("bob"), assignment_id=aid)
    grades = {g["student"]: g for g in prof.counted_grades(aid)}

    page = signed_in(browser, api, "prof")
    page.click("text=Class dashboard")
    page.click(f"a[href='/assignments/{aid}']")
    page.wait_for_selector("#students")
    assert page.inner_text("h1") == f"Assignment {aid}: Week 3 checkpoints"
    settings = page.inner_text("#settings")
    assert "CET" in settings and "10% per started day, at most 30%" in settings and "immediate; C3 on release" in settings and "not released yet" in settings
    counted = page.locator("#students tr.counts")
    assert counted.count() == 2  # alice's first attempt and bob's
    alice = page.locator(f"#attempt-{first['id']}").inner_text()
    assert f"{grades['alice']['counted_score']:g}" in alice and "−20%" in alice and "2 days charged" in alice
    bob = page.locator("#students tbody tr", has_text="bob").first.inner_text()
    assert "extension" in bob and "granted by prof" in bob and "on time" in bob
    assert "no attempt yet" in page.locator("#student-s1001").inner_text()
    assert "own setting" in page.locator("#items").inner_text()
    SHOTS.mkdir(parents=True, exist_ok=True)
    page.screenshot(path=str(SHOTS / "assignment.png"), full_page=True)
    # The stylesheet came from the app itself.
    assert page.evaluate("getComputedStyle(document.querySelector('header.top')).display") == "flex"
    page.close()
    # A student asking for the page gets the 404 page.
    student = signed_in(browser, api, "alice")
    student.goto(f"{api.url}/assignments/{aid}")
    assert "Week 3 checkpoints" not in student.content()
    # Her own report: C3 pending until the release, the attempt that counts and the penalty named.
    student.goto(f"{api.url}/submissions/{first['id']}")
    student.wait_for_selector("#items")
    assert "pending" in student.locator("#item-C3").inner_text()
    assert "1 of 8 points pending (C3)" in student.inner_text("#pending")
    line = student.inner_text("#attempt")
    # Which attempt counts is the best score's secret until C3 is shown; the penalty follows from the lateness.
    assert "attempt 1" in line and "counts" not in line and "late penalty −20%" in line
    student.locator("#item-C3").scroll_into_view_if_needed()
    student.screenshot(path=str(SHOTS / "assignment-student-report.png"))
    prof.release(aid)
    student.reload()
    assert "pending" not in student.locator("#item-C3").inner_text()
    assert student.locator("#pending").count() == 0
    assert "counts" in student.inner_text("#attempt") and "counted 6.4" in student.inner_text("#attempt")
    # Graded on the lesson's own cases as already measured: each named in her case runs, reused, nothing run.
    runs = student.inner_text("#case-runs")
    assert runs.count("reused measurement of case run") == 7 and "N4" in runs and "friction-baseline" in runs
    assert "lesson's own cases as already measured" in student.inner_text("#check-line")
    student.screenshot(path=str(SHOTS / "assignment-student-report-released.png"), full_page=True)
    student.close()
