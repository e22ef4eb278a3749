"""The sheet form in a real browser (Debian's chromium driven by Playwright) over the real stack: a YAML imported,
a draft saved by the page's script as the student types and found in a new browser context, a two-factor config
caught by Check, and the form submitted and graded. Screenshots under out/screenshots/ (or $SCREENSHOTS_DIR)."""

from __future__ import annotations

import pytest
import yaml

from tests.factories import REFERENCE_YAML
from tests.integration.helpers import SHOTS, WAIT_LIMIT_S, signed_in

pytestmark = [pytest.mark.integration, pytest.mark.slow]


def test_a_student_fills_checks_and_submits_the_sheet_from_the_form(browser, stack):
    page = signed_in(browser, stack, "alice")
    page.goto(f"{stack.url}/sheet")
    page.set_input_files("#yaml-file", str(REFERENCE_YAML))
    page.click("#yaml button[type=submit]")
    page.wait_for_selector("#notice")
    assert page.is_checked("input[name='answers.A2.direction'][value='decrease']")
    with page.expect_download() as download:  # the form as YAML: the same data that went in
        page.click("button[value=export]")
    assert yaml.safe_load(open(download.value.path()).read()) == yaml.safe_load(REFERENCE_YAML.read_text())

    # Typing saves the draft through the page's script (no button pressed); a new context finds it.
    page.fill("[id='f-answers.C5.pair_friction']", "0.55")
    page.wait_for_selector("#draft-status:text-matches('^draft saved')")  # no script evaluated: the CSP forbids eval
    other = signed_in(browser, stack, "alice")
    other.goto(f"{stack.url}/sheet")
    assert other.input_value("[id='f-answers.C5.pair_friction']") == "0.55"
    other.context.close()

    # Two inputs of the hands-on config changed: Check shows the difference and the one-factor violation.
    page.fill("[id='f-answers.C5.pair_friction']", "0.5")
    page.click("#held-table_exercise > summary")  # dt is held fixed: read-only until "Change a held field"
    page.click("#held-table_exercise button.unlock-held")
    page.fill("[id='f-configs.table_exercise.dt']", "0.02")
    page.click("button[value=check]")
    page.wait_for_selector("#one-factor")
    verdict = page.inner_text("#check-table_exercise")
    assert "one-factor violation" in verdict
    assert "may not change" in page.inner_text("#one-factor")
    page.locator("#one-factor").scroll_into_view_if_needed()
    page.screenshot(path=SHOTS / "sheet_form_one_factor.png", full_page=False)

    # Put back, check again (no violation), submit, and the report comes.
    page.fill("[id='f-configs.table_exercise.dt']", "0.01")  # opened again: the draft held a changed field
    page.click("button[value=check]")
    page.wait_for_selector("#one-factor")
    assert "one-factor violation" not in page.inner_text("#one-factor")
    assert "passes every rule" in page.inner_text("#check-summary")
    page.screenshot(path=SHOTS / "sheet_form.png", full_page=True)
    page.click("button[value=submit]")
    page.click("#confirm-submit")  # the confirmation (attempt, lateness, penalty) comes first
    page.wait_for_url(f"{stack.url}/submissions/*/progress")
    submission = int(page.url.split("/")[-2])
    final = stack.client("alice").wait(submission, poll_s=0.5, timeout_s=WAIT_LIMIT_S)
    assert final["status"] == "graded", final
