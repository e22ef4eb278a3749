"""The pages in a real browser (Debian's chromium driven by Playwright) over the real stack: API over HTTP, a
Celery worker on Redis, PostgreSQL, real Genesis runs. Screenshots are kept under out/screenshots/ (or
$SCREENSHOTS_DIR) as test artifacts."""

from __future__ import annotations

import pytest

from tests.integration.helpers import SHOTS, charts_drawn, signed_in

pytestmark = [pytest.mark.integration, pytest.mark.slow]


def test_a_student_signs_in_and_reads_her_report_item_by_item(browser, stack, graded):
    submission = graded["alice"]["id"]
    grade = stack.client("alice").grade(submission)
    page = signed_in(browser, stack, "alice")
    page.click(f"a[href='/submissions/{submission}']")
    page.wait_for_selector("#items")
    assert page.inner_text("#total").split() == [f"{grade['total']:g}", "/", f"{grade['max_total']:g}", "points"]
    rows = page.locator("#items tbody tr")
    assert rows.count() == len(grade["items"])
    for item in grade["items"]:
        row = page.locator(f"#item-{item['id']}")
        assert row.locator(".verdict").inner_text() in ("credit", "inconclusive (not counted)"), item["id"]
        if item["measured"]:
            assert item["measured"] in row.inner_text(), item["id"]
    # A measured item shows its reviewed tolerance with the rationale behind it.
    b3 = page.locator("#item-B3")
    b3.locator("summary").first.click()
    assert "high_lane_unchanged = 0.01 m" in b3.inner_text() and "reviewed by" in b3.inner_text()
    # Every case ran on the CPU, and the page says so with the engine's own discretization.
    runs = stack.client("alice").case_runs(submission)
    assert page.locator("#case-runs tbody tr").count() == len(runs)
    page.locator("#provenance summary").first.click()
    provenance = page.locator("#provenance details").first.inner_text()
    assert "cpu / cpu" in provenance and "genesis 1.3.3" in provenance
    # The figures, drawn in the browser from the series the app serves with the session cookie: every chart drawn,
    # the student's own table exercise among them (tests/integration/test_report_charts_browser.py zooms them).
    charts = page.locator("#figures .chart[data-src]")
    assert charts.count() >= 5
    assert page.locator("[id='chart-friction-x-sheet.table_exercise']").count() == 1
    charts_drawn(page)  # every chart drawn, none failed
    download = page.request.get(f"{stack.url}/submissions/{submission}/results.json")  # with the session cookie
    assert download.ok and download.json()["total"] == grade["total"]
    assert [i["id"] for i in download.json()["items"]] == [i["id"] for i in grade["items"]]
    page.screenshot(path=SHOTS / "student_report.png", full_page=True)


def test_a_lost_item_shows_what_the_measurement_showed_instead(browser, stack, graded):
    submission = graded["bob"]["id"]
    page = signed_in(browser, stack, "bob")
    page.goto(f"{stack.url}/submissions/{submission}")
    h3 = page.locator("#item-H3")
    assert "lost" in h3.get_attribute("class")
    assert h3.locator(".verdict").inner_text() == "no credit"
    text = h3.inner_text()
    assert "high: farther" in text and "delta" in text and "sheet.table_exercise on cpu" in text
    page.locator("#item-H3").scroll_into_view_if_needed()
    page.screenshot(path=SHOTS / "student_report_lost_item.png", full_page=False)
    phone = signed_in(browser, stack, "bob", width=390)
    phone.goto(f"{stack.url}/submissions/{submission}")
    assert phone.evaluate("document.documentElement.scrollWidth") <= 390 + 1, "the report scrolls sideways on a phone"
    phone.screenshot(path=SHOTS / "student_report_phone.png", full_page=False)


def test_another_students_report_is_not_found_and_reveals_nothing(browser, stack, graded):
    page = signed_in(browser, stack, "alice")
    response = page.goto(f"{stack.url}/submissions/{graded['bob']['id']}")
    assert response.status == 404
    assert "bob" not in page.inner_text("main") and "H3" not in page.content()
    page.screenshot(path=SHOTS / "not_found.png")


def test_the_instructor_dashboard_shows_the_item_analysis_of_the_json(browser, stack, graded):
    data = stack.client("prof").dashboard("l03-test")
    page = signed_in(browser, stack, "prof")
    page.click("text=Class dashboard")
    page.wait_for_selector("#item-analysis-L03")
    # Each student's latest graded attempt counts: whatever else the session graded, Bob's H3 is a wrong answer.
    analysis = {item["id"]: item for item in data["analysis"]["items"]}
    assert analysis["H3"]["credit_share"] < 1.0
    assert any("farther" in w["prediction"] for w in analysis["H3"]["wrong_answers"])
    rows = page.locator("#item-analysis-L03 tbody tr")
    assert rows.count() == len(analysis)
    for item_id, item in analysis.items():
        cells = page.locator(f"#analysis-L03-{item_id} td")
        assert cells.nth(1).inner_text() == str(item["n"]), item_id
        assert cells.nth(2).inner_text().strip() == f"{round(100 * item['credit_share'])}%", item_id
        for wrong in item["wrong_answers"]:
            assert f"{wrong['prediction']} \u00d7 {wrong['count']}" in cells.nth(5).inner_text(), item_id
    roster = {r["student"]: r for r in data["roster"]}
    # her latest graded attempt: other modules of the session (the notebook routes) may have graded a later one
    latest = max(s["id"] for s in stack.client("alice").http.get("/submissions").json() if s["status"] == "graded")
    assert roster["alice"]["submission_id"] == latest >= graded["alice"]["id"] and roster["alice"]["attempts"] >= 2
    assert page.locator("#roster").inner_text().count("alice") == 1
    page.screenshot(path=SHOTS / "instructor_dashboard.png", full_page=True)
    student = signed_in(browser, stack, "alice")
    assert student.goto(f"{stack.url}/courses/l03-test/dashboard").status == 404
