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
from tests.integration.a11y import assert_accessible
from tests.integration.helpers import SHOTS, at, measured_course_api, signed_in
from tests.integration.layout import assert_fits, pages_in_both_languages

pytestmark = pytest.mark.integration
COURSE = "l03-review"
MESSAGE = "My C3 reason names the run the proxy shows as stable; please look at it again."
ANSWER = "You are half right: the run is right, the reason you picked is not the lesson's. Half a point."


@pytest.fixture(scope="module")
def api(tmp_path_factory, measured):
    """The API alone (uvicorn) on a fresh PostgreSQL database where the lesson's cases were measured."""
    with measured_course_api(tmp_path_factory.mktemp("review-override"), measured, course=COURSE) as running:
        yield running


def _signed_in(browser, api, who: str, *, locale: str = "en", width: int = 1280):
    page = browser.new_page(viewport={"width": width, "height": 900}, locale=locale)
    page.goto(f"{api.url}/submissions")
    page.fill("#token", api.tokens[who])
    page.click("form[action='/sign-in'] button[type=submit]")
    page.wait_for_selector("header .who")
    return page


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
    # the queue shows the item as it stands now: its score of its points and its measured verdict
    assert page.inner_text("#open-requests .item-now").startswith("Item now: 1 of 1 points · credit")
    SHOTS.mkdir(parents=True, exist_ok=True)
    page.screenshot(path=str(SHOTS / "review-queue.png"), full_page=True)
    queue = page.url.split("#")[0]
    pages_in_both_languages(browser, lambda b, **kw: _signed_in(b, api, "prof", **kw), queue, SHOTS, "review-queue",
                            ready="#open-requests")
    request = page.locator("#open-requests article.review").first
    request.locator("textarea[name=answer]").fill(ANSWER)
    request.locator("input[name=score]").fill("0.5")
    request.locator("button[type=submit]").click()
    page.wait_for_selector("#answered")
    assert "set to 0.5" in page.inner_text("#answered") and page.locator("#no-open").count() == 1
    assert "0.5 of 1 points, credit" in page.inner_text("#answered")  # the item now, after the answer's override
    assert_fits(page, "review queue, answered")
    page.screenshot(path=str(SHOTS / "review-queue-answered.png"), full_page=True)
    page.goto(f"{api.url}/submissions/{sid}")
    override = page.inner_text("#override-C3")
    assert "0.5 / 1" in override and ANSWER in override and "credit" in override
    page.locator("#review").screenshot(path=str(SHOTS / "report-override-instructor.png"))

    # A refused override (a score above the item's points, a comment of spaces) is the report again: the errors
    # beside the form, named by the form's labels, and what was typed kept; nothing is stored.
    for lang, width in (("en", 1280), ("zh-CN", 390), ("en", 390), ("zh-CN", 1280)):
        prof_page = _signed_in(browser, api, "prof", locale=lang, width=width)
        prof_page.goto(f"{api.url}/submissions/{sid}")
        prof_page.select_option("#override-item", "C2")
        prof_page.fill("#override-score", "3")
        prof_page.fill("#override-comment", "Typed with care: C2's reason is the lesson's own. " if lang == "en"
                       else "   ")
        prof_page.click("#override-form button[type=submit]")
        prof_page.wait_for_selector("#override-errors")
        errors = prof_page.inner_text("#override-errors")
        if lang == "en":
            assert "The score was not set; nothing was changed." in errors
            assert "New score: must be from 0 to 1, item C2's points" in errors and "\nscore:" not in errors
            assert prof_page.input_value("#override-comment") == "Typed with care: C2's reason is the lesson's own. "
        else:
            assert "分数未设置" in errors and "评语" in errors and "新分数" in errors
        assert prof_page.input_value("#override-score") == "3" and prof_page.input_value("#override-item") == "C2"
        assert prof_page.get_attribute("#override-score", "aria-invalid") == "true"
        assert prof_page.url.endswith(f"/submissions/{sid}/overrides#override-form")
        # on a phone the report's #case-runs and #lane-table scroll sideways: focusable, so a keyboard reaches them
        assert_accessible(prof_page, f"override refused ({lang}, {width} px)")
        prof_page.locator("#override-form").scroll_into_view_if_needed()
        prof_page.screenshot(path=str(SHOTS / f"report-override-refused-{lang[:2]}-{width}.png"), full_page=True)
        prof_page.close()
    assert "C2" not in page.inner_text("#overrides") if page.locator("#overrides").count() else True
    page.reload()
    assert "Typed with care" not in page.inner_text("#review")  # nothing stored
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
