"""The lab check and the sliding lanes on a student's report, in a real browser over the real stack (API, Celery worker
on Redis, PostgreSQL, real Genesis runs). The page must show exactly what the worker stored with the grade."""

from __future__ import annotations

import re

import pytest
from sqlalchemy import select
from sqlalchemy.orm import Session

from grader.core.models import Grade
from tests.factories import reference_sheet
from tests.integration.helpers import SHOTS, case_runs, charts_drawn, signed_in, submit_and_wait

pytestmark = [pytest.mark.integration, pytest.mark.slow]


def _stored_report(stack, submission_id: int) -> dict:
    with Session(stack.engine) as session:
        return session.scalar(select(Grade).where(Grade.submission_id == submission_id)).report


def test_a_student_reads_the_lab_check_stored_with_her_grade(browser, stack, graded):
    submission = graded["alice"]["id"]
    check = _stored_report(stack, submission)["check"]
    assert check is not None, "the worker stored no lab check with the grade"
    # The reference sheet's runs are the lesson's runs: the lab's own verdict on them is a pass.
    assert check["passed"] and check["verdict_line"] == "L03 CHECK: PASSED", check
    page = signed_in(browser, stack, "alice")
    page.goto(f"{stack.url}/submissions/{submission}")
    page.wait_for_selector("#lab-check")
    assert page.locator("#check-line code").inner_text() == check["verdict_line"]
    # Near the total: the line comes right after the summary card that holds it.
    assert page.evaluate("document.querySelector('.summary').nextElementSibling.id") == "check-line"
    conditions = page.locator("#lab-check li")
    assert conditions.count() == len(check["conditions"]) == 12
    for c in check["conditions"]:
        row = page.locator(f"#condition-{c['id']}")
        assert row.locator(".cond-state").inner_text() == ("passed" if c["passed"] else "FAILED"), c["id"]
        assert c["title"] in row.inner_text()
        assert not row.locator("pre.evidence").is_visible()  # folded until asked for
        row.locator("summary").click()
        assert row.locator("pre.evidence").inner_text() == c["evidence"], c["id"]
    # The conditions about a local lab run say what they mean in the service, in their evidence.
    assert "ARTIFACTS_DIR" in page.locator("#condition-outputs pre").inner_text()
    assert "rendering off" in page.locator("#condition-rendering pre").inner_text()
    page.screenshot(path=SHOTS / "student_report_check.png", full_page=True)


def test_each_sliding_lane_shows_its_stop_its_tilt_and_whether_it_tumbled(browser, stack, graded):
    submission = graded["alice"]["id"]
    friction = [r for r in case_runs(stack, submission) if r.metrics and r.metrics["kind"] == "friction"]
    # The lab check's runs and the student's own table exercise are all on the page.
    assert {"friction-baseline", "friction-table-0.30", "sheet.table_exercise"} <= {r.name for r in friction}
    page = signed_in(browser, stack, "alice")
    page.goto(f"{stack.url}/submissions/{submission}")
    for run in friction:
        for lane in run.metrics["lanes"].values():
            row = page.locator(f"[id='lane-{run.name}-{lane['lane']}']")
            text = row.inner_text()
            assert f"{lane['max_tilt_deg']:.1f}\u00b0" in text
            assert f"{lane['stop']['distance']:.3f} m" in text
            assert ("TUMBLED" in text) is lane["tumbled"], (run.name, lane)
    assert page.locator("#lanes .tumble-note").count() == any(
        lane["tumbled"] for r in friction for lane in r.metrics["lanes"].values())


def test_a_grade_stored_before_the_lab_check_says_so(browser, stack, graded):
    from sqlalchemy.orm.attributes import flag_modified

    submission = graded["alice_first"]["id"]
    with Session(stack.engine) as session:
        grade = session.scalar(select(Grade).where(Grade.submission_id == submission))
        saved = grade.report["check"]
        grade.report = {k: v for k, v in grade.report.items() if k != "check"}
        flag_modified(grade, "report")
        session.commit()
    try:
        page = signed_in(browser, stack, "alice")
        page.goto(f"{stack.url}/submissions/{submission}")
        assert page.locator("#check-line").inner_text() == "no lab check stored for this grade"
        assert page.locator("#lab-check").count() == 0
    finally:
        with Session(stack.engine) as session:
            grade = session.scalar(select(Grade).where(Grade.submission_id == submission))
            grade.report = {**grade.report, "check": saved}
            flag_modified(grade, "report")
            session.commit()


def test_a_grade_whose_figures_are_being_drawn_shows_the_score_and_refreshes_until_they_are(browser, stack, graded):
    """The state the worker leaves between storing a grade and completing it (worker.grading): the score is final,
    the check and the figures are not there yet, and the page says so and refreshes itself."""
    from sqlalchemy.orm.attributes import flag_modified

    submission = graded["bob"]["id"]
    with Session(stack.engine) as session:
        grade = session.scalar(select(Grade).where(Grade.submission_id == submission))
        saved, completed = grade.report["check"], grade.completed_at
        grade.report = {**grade.report, "check": None}
        grade.completed_at = None
        flag_modified(grade, "report")
        session.commit()
        total = grade.total
    try:
        page = signed_in(browser, stack, "bob")
        page.goto(f"{stack.url}/submissions/{submission}")
        page.screenshot(path=str(SHOTS / "report-figures-being-drawn.png"), full_page=False)
        assert page.locator("#total .big").inner_text() == f"{total:g}"
        line = page.locator("#check-line").inner_text()
        assert "Your grade above is stored and final" in line and "is being evaluated" in line, line
        assert page.locator('meta[http-equiv="refresh"]').count() == 1
        assert page.locator("#lab-check").count() == 0 and page.locator("text=Grading in progress").count() == 0
        state = stack.client("bob").submission(submission)
        assert state["status"] == "graded" and state["report_complete"] is False
    finally:
        with Session(stack.engine) as session:
            grade = session.scalar(select(Grade).where(Grade.submission_id == submission))
            grade.report, grade.completed_at = {**grade.report, "check": saved}, completed
            flag_modified(grade, "report")
            session.commit()
    page.reload()
    assert page.locator("#check-line").inner_text().startswith(saved["verdict_line"])
    assert page.locator('meta[http-equiv="refresh"]').count() == 0


def test_a_lane_whose_cube_tumbles_is_marked_with_why_its_stop_is_not_a_sliding_stop(browser, stack, graded):
    """Bob's table exercise raises table friction to 0.90 (one factor): on the pinned engine the cubes then pitch over
    their front edge (tests/worker/test_case_process.py), and the page and the figure must say so in words."""
    from rubric.metrics import TUMBLE_EXPLANATION

    sheet = reference_sheet() | {"student": "bob"}
    sheet["configs"]["table_exercise"]["table"]["friction"] = 0.90
    _, final = submit_and_wait(stack, sheet, who="bob")
    assert final["status"] == "graded", final
    run = next(r for r in case_runs(stack, final["id"]) if r.name == "sheet.table_exercise")
    lanes = run.metrics["lanes"]
    assert any(lane["tumbled"] for lane in lanes.values()), lanes
    page = signed_in(browser, stack, "bob")
    page.goto(f"{stack.url}/submissions/{final['id']}")
    for name, lane in lanes.items():
        row = page.locator(f"[id='lane-sheet.table_exercise-{name}']").inner_text()
        assert ("TUMBLED" in row and "not a sliding stop" in row) is lane["tumbled"], (name, row)
    assert TUMBLE_EXPLANATION in page.locator("#lanes .tumble-note").inner_text()
    # Its charts are drawn, and their caption says in words which lane tumbled.
    charts_drawn(page)
    caption = page.locator("[id='caption-friction-x-sheet.table_exercise']").inner_text()
    for name, lane in lanes.items():
        said = re.search(rf"{name} \(cube [^;]*", caption).group(0)  # the lane's part of the caption
        assert ("TUMBLED" in said and "not a sliding stop" in said) is lane["tumbled"], (name, caption)
    page.locator("#lanes").scroll_into_view_if_needed()
    page.screenshot(path=SHOTS / "student_report_tumbled_lane.png", full_page=False)
