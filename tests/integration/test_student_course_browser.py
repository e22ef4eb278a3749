"""A student signs in with a sign-in link and reads her course page in a real browser (Debian's chromium driven by
Playwright), with the keyboard alone, over the API on loopback with PostgreSQL. The lesson's own cases are stored as
really measured, so checkpoint sheets are graded in the request and no worker is needed. Screenshots land in
out/screenshots/ (or $SCREENSHOTS_DIR)."""

from __future__ import annotations

import pytest

from tests.grader.services.setup.test_assignments import checkpoint_sheet
from tests.integration.helpers import SHOTS, at, measured_course_api

pytestmark = pytest.mark.integration
COURSE = "l03-course"


@pytest.fixture(scope="module")
def service(tmp_path_factory, measured):
    """The API alone (uvicorn) on a fresh PostgreSQL database where the lesson's cases were measured."""
    with measured_course_api(tmp_path_factory.mktemp("course-page"), measured, course=COURSE) as running:
        yield running


def tab_to(page, selector: str, limit: int = 60) -> list[str]:
    """Press Tab until `selector` has the focus; what each stop was (tag, text or label), to read the tab order."""
    stops = []
    for _ in range(limit):
        page.keyboard.press("Tab")
        stops.append(page.evaluate("(() => { const e = document.activeElement; return e.tagName + ':' +"
                                   " (e.innerText || e.getAttribute('aria-label') || ''); })()"))
        if page.evaluate("(s) => document.activeElement.matches(s)", selector):
            return stops
    raise AssertionError(f"{selector} never took the focus; the tab stops were {stops}")


def test_a_student_signs_in_with_her_link_and_reads_her_course_page_with_the_keyboard(browser, service):
    prof = service.client("prof")
    prof.update_course(COURSE, {"timezone": "Asia/Shanghai"})
    (ada,) = prof.import_roster(COURSE, "student_id,name,email\ns1001,Ada Lovelace,ada@example.edu\n", links=True)
    week3 = prof.create_assignment(COURSE, {
        "title": "Week 3 checkpoints", "part": "checkpoints", "open_at": at(days=-1), "due_at": at(days=2),
        "hard_close_at": at(days=4), "late_penalty_per_day": 0.1, "max_attempts": 3, "max_per_hour": 2})
    week2 = prof.create_assignment(COURSE, {
        "title": "Week 2 checkpoints", "part": "checkpoints", "open_at": at(days=-5), "due_at": at(hours=-26),
        "hard_close_at": at(days=2), "late_penalty_per_day": 0.25, "counted_attempt": "best",
        "item_visibility": {"C3": "on_release"}})
    prof.create_assignment(COURSE, {"title": "Week 4 exercises", "part": "exercises", "open_at": at(days=3),
                                    "due_at": at(days=9), "hard_close_at": at(days=10)})
    student = service.client("s1001", ada["token"])
    first = student.submit(checkpoint_sheet("s1001"), assignment_id=week3["id"])
    student.submit(checkpoint_sheet("s1001"), assignment_id=week2["id"])

    context = browser.new_context(viewport={"width": 1280, "height": 900})
    page = context.new_page()
    page.goto(ada["sign_in_link"])
    assert "signs you in as s1001 (Ada Lovelace)" in page.inner_text("main")
    SHOTS.mkdir(parents=True, exist_ok=True)
    page.screenshot(path=SHOTS / "sign_in_link.png")
    tab_to(page, "main form button[type=submit]")
    page.keyboard.press("Enter")
    page.wait_for_url(f"{service.url}/courses/{COURSE}")
    assert page.inner_text("h1") == f"Course {COURSE}"
    assert "Asia/Shanghai" in page.inner_text("main")

    on_time = page.inner_text(f"#assignment-{week3['id']}")
    assert "1 used, 2 left of 3" in on_time and "2 submissions per hour (1 in the last hour)" in on_time
    assert "Accepted as attempt 2, on time, no late penalty." in page.inner_text(f"#assignment-{week3['id']}-now")
    # Week 2 withholds C3 until its release, and withholding is per student and lesson (issue 44): the same
    # checkpoints sent to Week 3 must not tell it, so Week 3's score waits for that release too, saying so.
    counted = page.inner_text(f"#assignment-{week3['id']}-counted")
    assert "not shown yet" in counted and "“Week 2 checkpoints” is released" in counted, counted
    assert "CST" in on_time  # the course's zone, named beside every time
    late_now = page.inner_text(f"#assignment-{week2['id']}-now")
    assert "1 d 2 h" in late_now and "(2 days charged): a late penalty of 50% of its score" in late_now
    # C3 waits for the release: the score is partly pending, and under "best" which attempt counts stays hidden.
    assert "not shown yet" in page.inner_text(f"#assignment-{week2['id']}-counted")
    assert "part pending" in page.inner_text(f"#assignment-{week2['id']}-attempts")
    assert page.inner_text(".assignment:has-text('Week 4 exercises') .state") == "not open yet"
    # The phase is said in words, never by colour alone.
    phases = [page.inner_text(f"#assignment-{a['id']}-phase") for a in (week3, week2)]
    assert phases == ["open", "open, past the due date"]
    SHOTS.mkdir(parents=True, exist_ok=True)
    page.screenshot(path=SHOTS / "student_course.png", full_page=True)

    # Keyboard alone: from the top of the page to the first attempt's report.
    page.evaluate("document.activeElement && document.activeElement.blur()")
    stops = tab_to(page, f"a[href='/submissions/{first['id']}']")
    assert stops[0].startswith("A:") and any(s == "A:Course" for s in stops)
    page.keyboard.press("Enter")
    page.wait_for_url(f"{service.url}/submissions/{first['id']}")
    page.wait_for_selector("#items")

    # The link worked once: opening it again (a forwarded mail) says so and signs nobody in.
    other = browser.new_context()
    again = other.new_page()
    again.goto(ada["sign_in_link"])
    assert "already used" in again.inner_text("main") and again.locator("main form").count() == 0
    response = again.request.post(ada["sign_in_link"])
    assert response.status == 410 and not other.cookies()
    other.close()
    context.close()
