"""A student's review request answered with an override, in a real browser (Debian's chromium driven by Playwright)
over the API on loopback with PostgreSQL. The lesson's own cases are stored as really measured (the session's
`measured` runs), so the checkpoint sheet is graded in the request on them and no worker is needed (nothing here runs a
case). The student's report, the course CSV and the Gradescope export then show the new score and the comment while
the measured verdict stays visible. Screenshots land in out/screenshots/ (or $SCREENSHOTS_DIR)."""

from __future__ import annotations

import csv
import io

import httpx
import pytest

from tests.grader.services.setup.test_assignments import checkpoint_sheet
from tests.integration.helpers import SHOTS, at, measured_course_api, signed_in

pytestmark = pytest.mark.integration
COURSE = "l03-review"
MESSAGE = "My C3 reason names the run the proxy shows as stable; please look at it again."
ANSWER = "You are half right: the run is right, the reason you picked is not the lesson's. Half a point."


@pytest.fixture(scope="module")
def api(tmp_path_factory, measured):
    """The API alone (uvicorn) on a fresh PostgreSQL database where the lesson's cases were measured."""
    with measured_course_api(tmp_path_factory.mktemp("review-override"), measured, course=COURSE) as running:
        yield running


def _get(api, who: str, path: str) -> httpx.Response:
    response = httpx.get(f"{api.url}{path}", headers={"Authorization": f"Bearer {api.tokens[who]}"}, timeout=30)
    assert response.status_code == 200, response.text
    return response


def test_a_review_request_answered_with_an_override_reaches_the_report_the_csv_and_gradescope(browser, api):
    prof = api.client("prof")
    aid = prof.create_assignment(COURSE, {"title": "Week 3 checkpoints", "part": "checkpoints", "open_at": at(days=-1),
                                          "due_at": at(days=1), "hard_close_at": at(days=2)})["id"]
    sid = api.client("alice").submit(checkpoint_sheet("alice"), assignment_id=aid)["id"]
    measured = {i["id"]: i for i in api.client("alice").grade(sid)["items"]}["C3"]
    assert (measured["verdict"], measured["score"]) == ("credit", 1)

    # The student asks from the report page.
    student = signed_in(browser, api, "alice")
    student.goto(f"{api.url}/submissions/{sid}")
    student.select_option("#review-item", "C3")
    student.fill("#review-message", MESSAGE)
    student.click("#review-request-form button[type=submit]")
    student.wait_for_selector("#review-requests")
    assert "open: waiting for an instructor" in student.inner_text("#review-requests")

    # The instructor finds it at the top of the dashboard, opens the queue and answers with a new score.
    page = signed_in(browser, api, "prof")
    page.goto(f"{api.url}/courses/{COURSE}/dashboard")
    assert "alice asks about C3" in page.inner_text("#what-changed")
    page.click("#open-reviews a[href*='/reviews#request-']")
    page.wait_for_selector("#open-requests")
    assert MESSAGE in page.inner_text("#open-requests")
    SHOTS.mkdir(parents=True, exist_ok=True)
    page.screenshot(path=str(SHOTS / "review-queue.png"), full_page=True)
    request = page.locator("#open-requests article.review").first
    request.locator("textarea[name=answer]").fill(ANSWER)
    request.locator("input[name=score]").fill("0.5")
    request.locator("button[type=submit]").click()
    page.wait_for_selector("#answered")
    assert "set to 0.5" in page.inner_text("#answered") and page.locator("#no-open").count() == 1
    page.screenshot(path=str(SHOTS / "review-queue-answered.png"), full_page=True)
    page.goto(f"{api.url}/submissions/{sid}")
    override = page.inner_text("#override-C3")
    assert "0.5 / 1" in override and ANSWER in override and "credit" in override
    page.locator("#review").screenshot(path=str(SHOTS / "report-override-instructor.png"))
    page.goto(f"{api.url}/courses/{COURSE}/dashboard")
    assert "C3 of submission" in page.inner_text("#recent-overrides")
    page.locator("#what-changed").screenshot(path=str(SHOTS / "dashboard-what-changed.png"))

    # The student's report: the new score, the comment, the answer, and the measured verdict beside them.
    student.goto(f"{api.url}/submissions/{sid}")
    row = student.inner_text("#item-C3")
    assert "0.5 / 1" in row and "credit" in row and "measured verdict; score set by an instructor" in row
    shown = student.inner_text("#override-C3")
    assert ANSWER in shown and "credit" in shown and "1 / 1" in shown  # the measured score stays beside it
    assert ANSWER in student.inner_text("#review-requests") and "score set to 0.5" in student.inner_text("#review-requests")
    assert student.inner_text("#total").startswith("7.5")
    student.locator("#item-C3").screenshot(path=str(SHOTS / "report-override-student-item.png"))
    student.locator("#review").screenshot(path=str(SHOTS / "report-override-student.png"))

    # The course CSV and the Gradescope export carry the new score and the comment, and say what was measured.
    (row,) = csv.DictReader(io.StringIO(_get(api, "prof", f"/v1/courses/{COURSE}/grades.csv").text))
    assert (row["C3"], row["total"]) == ("0.5", "7.5")
    assert ANSWER in row["overrides"] and "measured: credit, 1" in row["overrides"]
    results = _get(api, "prof", f"/v1/submissions/{sid}/gradescope.json").json()
    test = next(t for t in results["tests"] if t["name"].startswith("C3:"))
    assert results["score"] == 7.5 and test["score"] == 0.5
    assert ANSWER in test["output"] and "measured: credit" in test["output"]
    counted = api.client("prof").counted_grades(aid)
    assert counted[0]["counted_score"] == 7.5
    # The same export as the page serves it, downloaded in the instructor's browser session.
    with page.expect_download() as download:
        page.goto(f"{api.url}/courses/{COURSE}/dashboard")
        page.click("#csv-latest")
    assert ANSWER in download.value.path().read_text()
