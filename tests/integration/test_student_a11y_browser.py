"""Every page a student sees, checked by axe-core in a real browser (Debian's chromium driven by Playwright) over the
API on loopback with PostgreSQL: the test fails on any serious or critical violation (tests/integration/a11y.py). The
sheet form is also used with the keyboard alone: Tab to the inputs, Space on a radio, Enter on Submit and on the
confirmation. The lesson's own cases are stored as really measured, so a checkpoint sheet is graded in the request
and no worker is needed; a free sheet's runs wait in the queue, which is what its progress page shows."""

from __future__ import annotations

import pytest
import yaml

from grader.core.states import SubmissionState
from tests.factories import REFERENCE_YAML
from tests.grader.services.setup.test_assignments import checkpoint_sheet
from tests.integration.a11y import assert_accessible
from tests.integration.helpers import at, measured_course_api, wait_until
from tests.integration.test_student_course_browser import tab_to

pytestmark = pytest.mark.integration
COURSE = "l03-a11y"


@pytest.fixture(scope="module")
def service(tmp_path_factory, measured):
    with measured_course_api(tmp_path_factory.mktemp("a11y"), measured, course=COURSE) as running:
        yield running


FOUND: list[str] = []  # every page's serious or critical findings, so one run lists them all


def checked(page, what: str) -> None:
    """axe on the page as it is: its serious or critical violations kept for the end of the walk, the rest printed."""
    try:
        minor = assert_accessible(page, what)
    except AssertionError as exc:
        FOUND.append(str(exc))
        return
    if minor:
        print(f"{what}: minor or moderate axe findings: {[v['id'] for v in minor]}")


def test_every_student_page_passes_axe_and_the_form_works_with_the_keyboard_alone(browser, service, tmp_path):
    prof = service.client("prof")
    (ada,) = prof.import_roster(COURSE, "student_id,name,email\ns2001,Ada Byron,ada@example.edu\n", links=True)
    week = prof.create_assignment(COURSE, {
        "title": "Week 3 checkpoints", "part": "checkpoints", "open_at": at(days=-2), "due_at": at(hours=-3),
        "hard_close_at": at(days=3), "late_penalty_per_day": 0.1, "max_attempts": 3})
    context = browser.new_context(viewport={"width": 1280, "height": 900})
    page = context.new_page()

    page.goto(f"{service.url}/sign-in")
    checked(page, "the sign-in form")
    page.goto(ada["sign_in_link"])
    checked(page, "the sign-in link page")
    tab_to(page, "main form button[type=submit]")
    page.keyboard.press("Enter")
    page.wait_for_url(f"{service.url}/courses/{COURSE}")
    checked(page, "the course page")

    # The assignment's form: its YAML is imported, then the keyboard alone changes an answer and submits.
    sheet_file = tmp_path / "checkpoints.yaml"
    sheet_file.write_text(yaml.safe_dump(checkpoint_sheet("s2001")))
    page.goto(f"{service.url}/assignments/{week['id']}/sheet")
    checked(page, "an assignment's sheet form")
    page.set_input_files("#yaml-file", str(sheet_file))
    page.click("#yaml button[type=submit]")
    page.wait_for_selector("#notice")
    page.evaluate("document.activeElement && document.activeElement.blur()")
    radio = "input[name='answers.C6.pair_rule']"
    tab_to(page, f"{radio}:checked")
    before = page.evaluate("() => document.activeElement.value")
    page.keyboard.press("ArrowDown")  # within a radio group the arrows move the choice
    moved = page.evaluate("() => document.activeElement.value")
    assert moved != before and page.is_checked(f"{radio}[value='{moved}']")
    page.keyboard.press("ArrowUp")
    page.keyboard.press("Space")
    assert page.is_checked(f"{radio}[value='{before}']")
    tab_to(page, "[id='f-answers.C5.pair_friction']")
    page.keyboard.press("Control+A")
    page.keyboard.type("0.7")
    tab_to(page, "button[value=check]")
    page.keyboard.press("Enter")
    page.wait_for_selector("#check-summary:has-text('passes every rule')")
    checked(page, "the sheet form after Check")
    assert page.input_value("[id='f-answers.C5.pair_friction']") == "0.7"
    tab_to(page, "button[value=submit]")
    page.keyboard.press("Enter")
    page.wait_for_selector("#confirm")
    checked(page, "the confirmation")
    assert "late" in page.inner_text("#confirm-late") and "10%" in page.inner_text("#confirm-penalty")
    tab_to(page, "#confirm-submit")
    page.keyboard.press("Enter")
    page.wait_for_url(f"{service.url}/submissions/*")  # progress, then (graded in the request) the report
    page.wait_for_selector("#items")
    graded_url = page.url
    assert "/progress" not in graded_url
    checked(page, "the report of a graded submission")
    stored = service.client("s2001", ada["token"]).submission(int(graded_url.rsplit("/", 1)[1]))
    assert stored["status"] == SubmissionState.GRADED and stored["attempt"] == 1

    # The free sheet, its confirmation and the progress of runs that wait (no worker here).
    page.goto(f"{service.url}/sheet")
    checked(page, "the free sheet form")
    page.set_input_files("#yaml-file", str(REFERENCE_YAML))
    page.click("#yaml button[type=submit]")
    page.wait_for_selector("#notice")
    page.click("button[value=submit]")
    page.wait_for_selector("#confirm")
    checked(page, "the free sheet's confirmation")
    page.click("#confirm-submit")
    page.wait_for_url(f"{service.url}/submissions/*/progress")
    page.wait_for_selector("#runs")
    wait_until(lambda: page.get_attribute("#progress-live", "data-polls"), "the page's script to poll once", 30)
    checked(page, "the progress page")

    page.goto(f"{service.url}/submissions")
    checked(page, "the submissions list")
    page.goto(f"{service.url}/submissions/999999")
    checked(page, "the not-found page")
    # The error page: a form on another site posting to the service is refused, in words.
    page.goto(f"data:text/html,<form method=post action='{service.url}/sheet'>"
              "<button name=action value=save>go</button></form>")
    page.click("button")
    page.wait_for_url(f"{service.url}/sheet")
    assert "Refused" in page.inner_text("h1")
    checked(page, "the error page")
    context.close()
    assert not FOUND, "\n".join(FOUND)
