"""Two students of an assignment with a really measured variant pool read their own lab in a real browser (Debian's
chromium driven by Playwright) on the real stack (PostgreSQL, Redis, a Celery worker running Genesis on CPU): the
course page and the sheet form state their own parameters, never the other student's, in English for one and in
Chinese for the other; the form's config editor starts from their variant's baseline and the questions name their
numbers; axe finds nothing serious at desktop and phone width. Screenshots land in out/screenshots/ (or
$SCREENSHOTS_DIR) as variant_*.png."""

from __future__ import annotations

import pytest
from sqlalchemy import select
from sqlalchemy.orm import Session

import rubric
from rubric.variants import texts
from grader.core.models import Assignment, StudentVariant, User
from tests.integration.a11y import assert_accessible
from tests.integration.helpers import SHOTS, at, wait_until

pytestmark = [pytest.mark.integration, pytest.mark.xdist_group("variants")]

# The pool of tests/integration/test_variants.py's seed, three variants: its runs are reused by content key when both
# modules run in one session. v391-1 fails the lesson's own check on CPU; v391-2 and v391-3 are kept.
SEED, K = 391, 3
KEPT = ("v391-2", "v391-3")
DESKTOP, PHONE = {"width": 1280, "height": 900}, {"width": 390, "height": 844}


def variant_of(stack, assignment_id: int, name: str) -> str:
    with Session(stack.engine) as session:
        student = session.scalar(select(User).where(User.name == name))
        return session.scalar(select(StudentVariant).where(StudentVariant.assignment_id == assignment_id,
                                                           StudentVariant.student_id == student.id)).variant.name


def accessible_at_both_widths(page, what: str, shot: str) -> None:
    """axe at desktop and phone width (screenshots of both), the page left at desktop width."""
    for width, viewport in (("", DESKTOP), ("_phone", PHONE)):
        page.set_viewport_size(viewport)
        assert_accessible(page, f"{what} at {viewport['width']} px")
        page.screenshot(path=SHOTS / f"variant_{shot}{width}.png", full_page=True)
    page.set_viewport_size(DESKTOP)


def test_two_students_read_their_own_measured_lab_on_the_course_page_and_the_form(stack, browser):
    prof = stack.client("prof")
    assignment = prof.create_assignment("l03-test", {
        "title": "Own lab pages", "part": "sheet", "open_at": at(hours=1), "due_at": at(days=2),
        "hard_close_at": at(days=3)})
    aid = assignment["id"]
    students = prof.import_roster("l03-test", "student_id,name,email\nv34en,Lin Ada,lin@example.edu\n"
                                              "v34zh,Wang Li,wang@example.edu\n", links=True)
    tokens = {s["student"]: s["token"] for s in students}

    # variant space v1 and a budget of K: the measured pool this test was written on (issue 47 added v2 and drawing
    # further past drops)
    pool = prof.generate_variants(aid, {"seed": SEED, "k": K, "budget": K, "space_version": "1"})
    assert [v["id"] for v in pool["variants"]] == [f"v{SEED}-{n}" for n in range(1, K + 1)], pool
    pool = wait_until(lambda: (p := prof.variants(aid))["state"] == "ready" and p,
                      "the pool's variants measured and checked")
    assert tuple(v["id"] for v in pool["variants"] if v["state"] == "kept") == KEPT, pool["variants"]
    with Session(stack.engine) as session:  # the assignment opens once its pool is ready
        row = session.get(Assignment, aid)
        row.open_at = row.open_at.replace(year=row.open_at.year - 1)
        session.commit()

    drawn = {v.id: v for v in rubric.draw_pool(rubric.load_variant_space("L03", "1"), seed=SEED, k=K).variants}
    book = rubric.load_rubric("L03")
    seen = {}
    for who, locale in (("v34en", "en"), ("v34zh", "zh")):
        context = browser.new_context(viewport=DESKTOP, locale="zh-CN" if locale == "zh" else "en-US")
        page = context.new_page()
        page.goto(f"{stack.url}/sign-in")
        page.fill("#token", tokens[who])
        page.click("form[action='/sign-in'] button[type=submit]")
        page.goto(f"{stack.url}/courses/l03-test")
        assert page.get_attribute("html", "lang") == locale
        seen[who] = variant_of(stack, aid, who)  # fixed at this first view
        own = drawn[seen[who]]
        others = [v for name, v in drawn.items() if name != own.id]

        # The course page: their own parameters, in their language; nobody else's.
        summary = page.inner_text(f"#assignment-{aid}-lab-summary")
        assert summary == texts.parameter_summary(own, locale)
        card = page.inner_text(f"#assignment-{aid}")
        for other in others:
            assert texts.parameter_summary(other, locale) not in card
        page.click(f"#assignment-{aid}-lab-details summary")
        table = page.inner_text(f"#assignment-{aid}-lab-table_friction")
        assert texts.parameter_rows(own, locale)[10][2] in table  # table_friction, the variant's value
        accessible_at_both_widths(page, "the course page", f"course_{locale}")

        # The form: the same parameters at the top, the config editor at the variant's baseline, B1 with its numbers.
        page.click(f"#assignment-{aid}-answer")
        page.wait_for_url(f"{stack.url}/assignments/{aid}/sheet")
        assert page.inner_text("#your-lab-summary") == texts.parameter_summary(own, locale)
        main = page.inner_text("main")
        for other in others:
            assert texts.parameter_summary(other, locale) not in main
        friction = page.locator("[id='f-configs.table_exercise.table.friction']")
        assert friction.input_value() == repr(own.parameters["table_friction"])
        cube = page.locator("[id='f-configs.table_exercise.cube_size']")
        assert cube.input_value() == repr(own.parameters["cube_size"])
        question = page.inner_text("#item-B1 .question-text")
        assert question == texts.item_question(book.item("B1"), own, locale)
        assert f"{own.parameters['table_friction']:.2f}" in question
        assert question != texts.item_question(book.item("B1"), None, locale)
        accessible_at_both_widths(page, "the sheet form", f"form_{locale}")
        context.close()
    assert sorted(seen.values()) == sorted(KEPT)  # the two students hold the two kept variants
