"""The student's walk in Chinese, in a real browser (Debian's chromium driven by Playwright, its locale zh-CN, so
it sends Accept-Language zh-CN) over the API on loopback with PostgreSQL: a sign-in link, the course page, the sheet
form filled and submitted, the confirmation, and the report, every page in Chinese, with the switch back to English
on each. The lesson's own cases are stored as really measured, so a checkpoint sheet is graded in the request.
Screenshots of every page at desktop and phone width land in out/screenshots/ (or $SCREENSHOTS_DIR) as zh_*.png."""

from __future__ import annotations

import pytest
import yaml

from grader import i18n
from tests.grader.services.setup.test_assignments import checkpoint_sheet
from tests.integration.helpers import SHOTS, at, measured_course_api

pytestmark = pytest.mark.integration
COURSE = "l03-zh"
PHONE = {"width": 390, "height": 844}
DESKTOP = {"width": 1280, "height": 900}


@pytest.fixture(scope="module")
def service(tmp_path_factory, measured):
    with measured_course_api(tmp_path_factory.mktemp("chinese-walk"), measured, course=COURSE) as running:
        yield running


def shoot(page, name: str) -> None:
    """The page at desktop width (whole page) and at phone width (whole page), then back to desktop."""
    SHOTS.mkdir(parents=True, exist_ok=True)
    page.set_viewport_size(DESKTOP)
    page.screenshot(path=SHOTS / f"zh_{name}.png", full_page=True)
    page.set_viewport_size(PHONE)
    page.screenshot(path=SHOTS / f"zh_{name}_phone.png", full_page=True)
    page.set_viewport_size(DESKTOP)


def in_chinese(page) -> None:
    assert page.get_attribute("html", "lang") == "zh"
    assert page.inner_text("header .brand") == "Genesis 实验自动评分系统"
    # The switch names each language in its own language, and says which one is on.
    assert page.inner_text("form.language button[value=en]") == "English"
    assert page.get_attribute("form.language button[value=zh]", "aria-pressed") == "true"


def test_a_student_walks_from_her_link_to_her_report_in_chinese(browser, service, tmp_path):
    prof = service.client("prof")
    prof.update_course(COURSE, {"timezone": "Asia/Shanghai"})
    (ada,) = prof.import_roster(COURSE, "student_id,name,email\ns2001,李华,lihua@example.edu\n", links=True)
    week3 = prof.create_assignment(COURSE, {
        "title": "第 3 周概念检查", "part": "checkpoints", "open_at": at(days=-1), "due_at": at(days=2),
        "hard_close_at": at(days=4), "late_penalty_per_day": 0.1, "max_attempts": 3})

    context = browser.new_context(viewport=DESKTOP, locale="zh-CN")
    page = context.new_page()
    page.goto(ada["sign_in_link"])
    in_chinese(page)
    assert "此链接将以 s2001（李华）的身份登录课程 l03-zh" in page.inner_text("main")
    shoot(page, "sign_in_link")
    page.click("main form button[type=submit]")
    page.wait_for_url(f"{service.url}/courses/{COURSE}")

    in_chinese(page)
    assert page.inner_text("h1") == f"课程 {COURSE}"
    card = page.inner_text(f"#assignment-{week3['id']}")
    assert "开放中" in card and "每迟交一天（不足一天按一天计）扣 10%" in card and "共 3 次，剩余 3 次" in card
    assert "年" in card and "CST" in card  # dates as Chinese writes them, in the course's zone
    assert "将作为第 1 次提交，" in page.inner_text(f"#assignment-{week3['id']}-now")
    shoot(page, "course")

    page.click(f"#assignment-{week3['id']}-answer")
    page.wait_for_url(f"{service.url}/assignments/{week3['id']}/sheet")
    in_chinese(page)
    table = i18n.lesson_text("L03", "zh")
    from rubric import load_rubric

    assert page.inner_text("#item-C1 .question-text") == table["questions"][load_rubric("L03").item("C1").question]
    sheet = tmp_path / "checkpoints.yaml"
    sheet.write_text(yaml.safe_dump(checkpoint_sheet("s2001"), allow_unicode=True))
    page.set_input_files("#yaml-file", str(sheet))
    page.click("#yaml button[type=submit]")
    page.wait_for_selector("#notice")
    assert "已将 checkpoints.yaml 导入草稿" in page.inner_text("#notice")
    # One answer typed in the form, through its Chinese label; the page's script saves the draft in Chinese.
    page.fill("[id='f-answers.C5.pair_friction']", "0.5")
    page.wait_for_selector("#draft-status:text-matches('^草稿已保存')")
    shoot(page, "sheet_form")

    page.click("button[value=submit]")
    page.wait_for_selector("#confirm-submit")
    in_chinese(page)
    shoot(page, "submit_confirm")
    page.click("#confirm-submit")
    page.wait_for_url(f"{service.url}/submissions/*/progress")
    submission = int(page.url.rstrip("/").split("/")[-2])
    in_chinese(page)
    # A checkpoint sheet is graded in the request: the progress page says so and leads on to the report itself.
    page.wait_for_url(f"{service.url}/submissions/{submission}")
    page.wait_for_selector("#items")
    in_chinese(page)
    assert f"提交 {submission}" in page.inner_text("h1")
    assert page.inner_text("#submission-status") == "已评分"
    items = page.inner_text("#items")
    assert "概念检查点" in items and "你的预测" in items and "判定" in items
    assert table["questions"][load_rubric("L03").item("C5").question] in items
    assert " 分" in page.inner_text("#total")
    shoot(page, "report")

    # The report shows the grade the API stores (in English there), whatever language the pages were in.
    grade = service.client("s2001", ada["token"]).grade(submission)
    assert page.inner_text("#total .big") == i18n.number(grade["total"], "zh")

    # The switch: one press, and every page is English from then on in this browser, Accept-Language or not.
    page.click("form.language button[value=en]")
    page.wait_for_url(f"{service.url}/submissions/{submission}")
    assert page.get_attribute("html", "lang") == "en" and "Submission" in page.inner_text("h1")
    page.goto(f"{service.url}/courses/{COURSE}")
    assert page.inner_text("h1") == f"Course {COURSE}"
    context.close()
