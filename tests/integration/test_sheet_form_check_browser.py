"""Issue 33 in a real browser (Debian's chromium driven by Playwright) over the API on loopback with PostgreSQL, the
lesson's own cases stored as really measured (so the page can name the items a broken config voids): the config
editor with only the fields the lesson lets change editable, a held field changed and its warning at once, Check's
summary at the top (focused) with the one-factor violation, the confirmation repeating it and asking for a second
tick, a refusal in the reader's words, and the draft's time in the course's zone; in English and Chinese, at desktop
and phone width, each page checked with axe. Screenshots land in out/screenshots/ (or $SCREENSHOTS_DIR) as
sheet33_*.png."""

from __future__ import annotations

import re

import pytest
import yaml

from tests.factories import REFERENCE_YAML
from tests.grader.services.setup.test_assignments import checkpoint_sheet
from tests.integration.a11y import assert_accessible
from tests.integration.helpers import SHOTS, at, measured_course_api

pytestmark = [pytest.mark.integration, pytest.mark.slow]
COURSE = "l03-i33"
PHONE = {"width": 390, "height": 844}
DESKTOP = {"width": 1280, "height": 900}
ISO_TIME = re.compile(r"[0-9]{4}-[0-9]{2}-[0-9]{2}T[0-9]{2}:")
# Changing a held field of the hands-on config voids what compares its run (tests/rubric/test_scoring.py).
VOIDED = "B1, B3, H1, H2, H3, H4"


@pytest.fixture(scope="module")
def service(tmp_path_factory, measured):
    with measured_course_api(tmp_path_factory.mktemp("sheet-check"), measured, course=COURSE) as running:
        running.client("prof").update_course(COURSE, {"timezone": "Asia/Kolkata"})  # a half-hour zone: not UTC
        yield running


def sign_in(browser, service, who: str, locale: str, viewport: dict):
    context = browser.new_context(viewport=viewport, locale=locale)
    page = context.new_page()
    page.goto(f"{service.url}/submissions")
    page.fill("#token", service.tokens[who])
    page.click("form[action='/sign-in'] button[type=submit]")
    return page


def shoot(page, name: str) -> None:
    """The page at desktop and phone width (the viewport where the eye is, and the whole page), then as it was."""
    SHOTS.mkdir(parents=True, exist_ok=True)
    size = page.viewport_size
    for width, viewport in (("desktop", DESKTOP), ("phone", PHONE)):
        page.set_viewport_size(viewport)
        page.screenshot(path=SHOTS / f"sheet33_{name}_{width}.png", full_page=False)
        page.screenshot(path=SHOTS / f"sheet33_{name}_{width}_full.png", full_page=True)
    page.set_viewport_size(size)


def import_reference(page, service) -> None:
    page.goto(f"{service.url}/sheet")
    page.set_input_files("#yaml-file", str(REFERENCE_YAML))
    page.click("#yaml button[type=submit]")
    page.wait_for_selector("#notice")


def editable_config_inputs(page, role: str, *, labels: bool = False) -> list[str]:
    """The editable inputs of a config: those of the physics, or with `labels` its name and colours, which the
    one-factor rule never counts and which are edited freely, outside the held lock (issue 49)."""
    found = page.locator(f"#config-{role} input:not([type=hidden]):not([readonly]), "
                         f"#config-{role} select:not([disabled])")
    return found.evaluate_all("(els, labels) => els.filter(e => !!e.closest('.labels') === labels).map(e => e.name)",
                              labels)


def change_held_dt(page) -> None:
    page.click("#held-table_exercise > summary")
    page.click("#held-table_exercise button.unlock-held")
    page.fill("[id='f-configs.table_exercise.dt']", "0.02")
    page.wait_for_selector("#held-warning-table_exercise", state="visible")


def focused(page, selector: str) -> bool:
    return page.locator(selector).evaluate("el => el === document.activeElement")


def test_a_violation_is_at_the_top_after_check_and_on_the_confirmation(browser, service):
    page = sign_in(browser, service, "alice", "en-US", DESKTOP)
    import_reference(page, service)
    # Only the field the hands-on exercise changes is editable; the rest are held, read-only, behind a <details>.
    assert editable_config_inputs(page, "table_exercise") == ["configs.table_exercise.table.friction"]
    assert editable_config_inputs(page, "extension") == ["configs.extension.dt", "configs.extension.substeps"]
    named = editable_config_inputs(page, "table_exercise", labels=True)
    assert "configs.table_exercise.name" in named and "configs.table_exercise.lanes.0.color.0" in named, named
    assert not page.is_visible("[id='f-configs.table_exercise.dt']")
    assert page.inner_text("label[for='f-configs.table_exercise.table.friction']") == "table friction"
    page.click("#held-table_exercise > summary")
    assert page.inner_text("label[for='f-configs.table_exercise.gravity.2']") == "gravity z (m/s²)"
    assert not page.is_editable("[id='f-configs.table_exercise.dt']")
    page.locator("#config-table_exercise").scroll_into_view_if_needed()
    shoot(page, "en_config_editor")
    assert_accessible(page, "the sheet form's config editor")

    # The draft's time, saved as the student types: the course's zone, the page's date format.
    page.fill("[id='f-answers.C5.pair_friction']", "0.55")
    page.wait_for_selector("#draft-status:text-matches('^draft saved')")
    status = page.inner_text("#draft-status")
    assert status.endswith(" IST") and "UTC" not in status and not ISO_TIME.search(status), status
    page.fill("[id='f-answers.C5.pair_friction']", "0.5")

    # A clean sheet passes; the summary at the top says so, and has focus.
    page.click("button[value=check]")
    page.wait_for_selector("#check-summary")
    assert focused(page, "#check-summary")
    assert "The sheet passes every rule a submission checks." in page.inner_text("#check-summary")

    # A held field changed: the warning names what it voids at once, before any Check.
    change_held_dt(page)
    assert VOIDED in page.inner_text("#held-warning-table_exercise")
    page.fill("[id='f-configs.table_exercise.dt']", "0.01")  # put back: the warning goes
    page.wait_for_selector("#held-warning-table_exercise", state="hidden")
    page.fill("[id='f-configs.table_exercise.dt']", "0.02")
    page.wait_for_selector("#held-warning-table_exercise", state="visible")
    page.locator("#config-table_exercise").scroll_into_view_if_needed()
    shoot(page, "en_held_changed")

    # Check: the violation and the items it voids at the top of the page, focused; "passes" is not said.
    page.click("button[value=check]")
    page.wait_for_selector("#check-summary")
    assert focused(page, "#check-summary")
    top = page.inner_text("#check-summary")
    assert "one-factor violation" in top and "dt may not change" in top and VOIDED in top, top
    assert "passes every rule" not in page.inner_text("main")
    box = page.locator("#check-summary").bounding_box()
    assert box["y"] < DESKTOP["height"] and page.evaluate("window.scrollY") < box["y"] + box["height"]
    assert_accessible(page, "the sheet form after Check with a one-factor violation")
    shoot(page, "en_check_violation")

    # Submit: the confirmation repeats it, and submitting takes the second tick.
    page.click("button[value=submit]")
    page.wait_for_selector("#confirm-voids")
    voids = page.inner_text("#confirm-voids")
    assert "dt may not change" in voids and "dt 0.01 → 0.02" in voids and VOIDED in voids, voids
    assert_accessible(page, "the confirmation with a one-factor violation")
    shoot(page, "en_confirm_violation")
    url = page.url
    page.click("#confirm-submit")  # not ticked: the browser keeps the page (the server refuses it too)
    assert page.url == url and page.is_visible("#confirm-voids")
    page.check("#accept-voids")
    page.click("#confirm-submit")
    page.wait_for_url(f"{service.url}/submissions/*/progress")
    page.context.close()


def test_the_same_in_chinese_at_phone_width_and_a_refusal_in_the_readers_words(browser, service, tmp_path):
    page = sign_in(browser, service, "bob", "zh-CN", PHONE)
    import_reference(page, service)
    assert page.get_attribute("html", "lang") == "zh"
    assert editable_config_inputs(page, "table_exercise") == ["configs.table_exercise.table.friction"]
    assert page.inner_text("label[for='f-configs.table_exercise.table.friction']") == "桌面摩擦"
    page.fill("[id='f-answers.C5.pair_friction']", "0.5")
    page.wait_for_selector("#draft-status:text-matches('^草稿已保存')")
    status = page.inner_text("#draft-status")
    assert "年" in status and status.endswith(" IST") and "UTC" not in status, status
    page.locator("#config-table_exercise").scroll_into_view_if_needed()
    shoot(page, "zh_config_editor")

    change_held_dt(page)
    assert VOIDED in page.inner_text("#held-warning-table_exercise")
    page.click("button[value=check]")
    page.wait_for_selector("#check-summary")
    assert focused(page, "#check-summary")
    top = page.inner_text("#check-summary")
    assert "违反单因素规则" in top and VOIDED in top and "one-factor violation" not in top, top
    assert_accessible(page, "the Chinese sheet form after Check")
    shoot(page, "zh_check_violation")
    page.click("button[value=submit]")
    page.wait_for_selector("#confirm-voids")
    assert VOIDED in page.inner_text("#confirm-voids") and "dt 0.01 → 0.02" in page.inner_text("#confirm-voids")
    assert "我知道这些题目将作废，仍然提交" in page.inner_text("label:has(#accept-voids)")
    assert_accessible(page, "the Chinese confirmation with a one-factor violation")
    shoot(page, "zh_confirm_violation")

    # An assignment not open yet: Submit is refused at the top, once, by its title, in the course's zone.
    prof = service.client("prof")
    week = prof.create_assignment(COURSE, {"title": "Week 3 checkpoints", "part": "checkpoints",
                                           "open_at": at(days=1), "due_at": at(days=2), "hard_close_at": at(days=3)})
    sheet_file = tmp_path / "checkpoints.yaml"
    sheet_file.write_text(yaml.safe_dump(checkpoint_sheet("alice")))
    for locale, viewport, name in (("zh-CN", PHONE, "zh"), ("en-US", DESKTOP, "en")):
        student = sign_in(browser, service, "alice", locale, viewport)
        student.goto(f"{service.url}/assignments/{week['id']}/sheet")
        student.set_input_files("#yaml-file", str(sheet_file))
        student.click("#yaml button[type=submit]")
        student.wait_for_selector("#notice")
        student.click("button[value=submit]")
        student.wait_for_selector("#check-summary")
        assert focused(student, "#check-summary")
        main = student.inner_text("main")
        top = student.inner_text("#check-summary")
        assert "Week 3 checkpoints" in top and " IST" in top and not ISO_TIME.search(main), top
        assert "assignment_id" not in main and f"assignment {week['id']}" not in main
        assert main.count("“Week 3 checkpoints”于" if name == "zh" else "“Week 3 checkpoints” opens at") == 1, main
        assert_accessible(student, f"a refused Submit ({name})")
        shoot(student, f"{name}_refused")
        student.context.close()
    page.context.close()

