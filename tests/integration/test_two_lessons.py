"""A course runs two lessons (issue 45): an instructor creates an L02 and an L03 assignment in one course, a student
submits each through the API, and each is graded by its own lesson on its own real Genesis runs, with its own lab
check; the course's dashboard and exports carry both. Nothing outside lessons/l02 names L02."""

from __future__ import annotations

import copy
import csv
import io
from pathlib import Path

import httpx
import pytest
import yaml

from rubric import load_rubric
from tests.factories import reference_sheet
from tests.integration.a11y import assert_accessible
from tests.integration.helpers import (SHOTS, WAIT_LIMIT_S, at, case_runs, charts_drawn, events, signed_in,
                                       wait_until)

pytestmark = [pytest.mark.integration, pytest.mark.slow]
L02_YAML = Path(__file__).resolve().parents[2] / "examples" / "l02" / "reference.yaml"
L02_REFERENCE = yaml.safe_load(L02_YAML.read_text())
# A course of its own on the session's stack: its students' attempts never become another module's latest ones.
COURSE = "two-lessons"
PEOPLE = (("prof", "instructor"), ("alice", "student"), ("bob", "student"))


def _assignment(stack, lesson: str, part: str) -> int:
    made = httpx.post(f"{stack.url}/v1/courses/{COURSE}/assignments", headers=_auth(stack, "prof"), json={
        "title": f"{lesson} {part}", "lesson": lesson, "part": part, "open_at": at(days=-1), "due_at": at(days=30),
        "hard_close_at": at(days=31)})
    assert made.status_code == 201, made.text
    assert made.json()["lesson"] == lesson
    return made.json()["id"]


def _auth(stack, who: str) -> dict:
    return {"Authorization": f"Bearer {TOKENS[who]}"}


TOKENS: dict[str, str] = {}


@pytest.fixture(scope="module")
def course(stack):
    """The course's instructor and two students, their tokens in TOKENS, and a view of the stack that signs in as
    them (stack.client, signed_in)."""
    from dataclasses import replace

    from sqlalchemy.orm import Session

    from grader.services.identity import accounts

    with Session(stack.engine) as session:
        made = accounts.get_or_create_course(session=session, name=COURSE)
        for name, role in PEOPLE:
            user = accounts.get_or_create_user(session=session, course=made, name=f"{COURSE}-{name}", role=role)
            TOKENS[name] = accounts.create_token(session=session, user=user)
        session.commit()
    return replace(stack, tokens=dict(TOKENS))


@pytest.fixture(scope="module")
def assignments(course) -> dict[str, int]:
    return {"L02": _assignment(course, "L02", "sheet"), "L03": _assignment(course, "L03", "checkpoints")}


def test_an_assignment_of_a_lesson_not_installed_is_refused_naming_the_installed_ones(course):
    stack = course
    made = httpx.post(f"{stack.url}/v1/courses/{COURSE}/assignments", headers=_auth(stack, "prof"), json={
        "title": "L09", "lesson": "L09", "open_at": at(days=-1), "due_at": at(days=30), "hard_close_at": at(days=31)})
    assert made.status_code == 422, made.text
    assert "'L09' is not an installed lesson (installed: L02, L03)" in made.text


def test_a_sheet_of_the_other_lesson_is_refused_by_an_assignment_and_nothing_is_stored(course, assignments):
    stack = course
    client = stack.client("bob")
    before = len(client.http.get("/submissions").json())
    refused = client.http.post("/submissions", json={"sheet": copy.deepcopy(L02_REFERENCE),
                                                     "assignment_id": assignments["L03"]})
    assert refused.status_code == 422, refused.text
    assert "is for lesson L03" in refused.text
    assert len(client.http.get("/submissions").json()) == before


def test_one_student_is_graded_on_each_lesson_by_its_own_runs_and_lab_check(course, assignments):
    stack = course
    client = stack.client("alice")
    l02 = client.submit(copy.deepcopy(L02_REFERENCE), assignment_id=assignments["L02"])
    checkpoints = reference_sheet()
    checkpoints["answers"] = {k: v for k, v in checkpoints["answers"].items() if k.startswith("C")}
    checkpoints.pop("configs")
    l03 = client.submit(checkpoints, assignment_id=assignments["L03"])
    finals = {lesson: client.wait(made["id"], poll_s=0.5, timeout_s=WAIT_LIMIT_S)
              for lesson, made in (("L02", l02), ("L03", l03))}
    assert {lesson: final["status"] for lesson, final in finals.items()} == {"L02": "graded", "L03": "graded"}, finals

    # client.wait returned each with its report complete: the lab check added (worker.grading.complete_grade), or
    # none wanted (a checkpoint sheet graded at once in its request, below).
    grade = client.grade(l02["id"])
    book = load_rubric("L02")
    assert (grade["rubric_lesson"], grade["rubric_version"], grade["rubric_hash"]) == ("L02", "1", book.content_hash)
    assert [(i["id"], i["verdict"]) for i in grade["items"]] == [(item.id, "credit") for item in book.items]
    assert grade["total"] == grade["max_total"] == 22
    assert grade["check"]["verdict_line"] == "L02 CHECK: PASSED", grade["check"]
    runs = {run.name: run for run in case_runs(stack, l02["id"])}
    assert sorted(runs) == ["S1", "S2", "sheet.exercise"]
    assert all(run.status == "done" and run.spec["kind"] == "drop" and run.actual_backend == "cpu"
               for run in runs.values()), runs
    assert runs["sheet.exercise"].spec["dt"] == 0.004 and runs["sheet.exercise"].metrics["samples"] == 150

    grade = client.grade(l03["id"])
    assert grade["rubric_lesson"] == "L03" and [i["id"] for i in grade["items"]] == [f"C{n}" for n in range(1, 9)]
    # A checkpoint sheet whose cases some earlier submission on this stack measured (another module's, in the suite's
    # shuffled order) is graded at once in its request on those runs, without a lab check (grader.services.submissions
    # .submit); measured for it, the worker adds L03's check. CI of 2026-12-08 waited 900 s for a check of the first
    # kind: which one happened is read from the submission's events, and each is asserted for what it is.
    at_once = any("graded at once" in (e.detail or "") for e in events(stack, l03["id"]))
    if at_once:
        assert grade["check"] is None and all(run.reused_from_id for run in case_runs(stack, l03["id"])), grade
    else:
        assert grade["check"]["verdict_line"] == "L03 CHECK: PASSED", grade["check"]
    assert {run.spec["kind"] for run in case_runs(stack, l03["id"])} == {"contact", "friction"}

    # The instructor's course views carry both lessons' grades.
    # The course's grades file: a lesson column, and each item's column named with its lesson (C1 is a question of
    # both lessons, and not the same question).
    table = list(csv.DictReader(io.StringIO(httpx.get(f"{stack.url}/v1/courses/{COURSE}/grades.csv",
                                                      headers=_auth(stack, "prof")).text)))
    rows = {row["submission_id"]: row for row in table}
    assert (rows[str(l02["id"])]["lesson"], rows[str(l03["id"])]["lesson"]) == ("L02", "L03")
    assert (rows[str(l02["id"])]["L02.C2"], rows[str(l02["id"])]["L03.C2"], rows[str(l03["id"])]["L03.C2"]) == (
        "3", "", "1")
    # The dashboard's item analysis is per lesson: L02's C1 and L03's C1 are different questions, never one row.
    dashboard = httpx.get(f"{stack.url}/v1/courses/{COURSE}/dashboard", headers=_auth(stack, "prof"))
    assert dashboard.status_code == 200, dashboard.text
    data = dashboard.json()
    assert data["lessons"] == ["L02", "L03"] and data["students_graded"] == 1, data["lessons"]
    analyses = {a["lesson"]: a["analysis"] for a in data["analyses"]}
    assert {lesson: a["n_reports"] for lesson, a in analyses.items()} == {"L02": 1, "L03": 1}
    assert [i["id"] for i in analyses["L02"]["items"]] == [item.id for item in book.items]
    assert [i["id"] for i in analyses["L03"]["items"]] == [f"C{n}" for n in range(1, 9)]
    assert analyses["L02"]["mean_total"] == 22 and analyses["L02"]["max_total"] == 22
    assert data["lesson"] == "L03" and data["analysis"] == analyses["L03"]  # the latest submission's lesson
    c1 = {lesson: next(i["question"] for i in a["items"] if i["id"] == "C1") for lesson, a in analyses.items()}
    assert c1["L02"] != c1["L03"], c1
    html = httpx.get(f"{stack.url}/courses/{COURSE}/dashboard", headers=_auth(stack, "prof")).text
    assert 'id="item-analysis-L02"' in html and 'id="item-analysis-L03"' in html
    assert 'id="analysis-L02-P1"' in html and 'id="analysis-L03-C8"' in html and "Lessons L02, L03" in html
    exported = httpx.get(f"{stack.url}/v1/submissions/{l02['id']}/gradescope.json", headers=_auth(stack, "prof"))
    assert exported.status_code == 200 and exported.json()["score"] == 22, exported.text

    # The student's report page and its data: the lesson's own check line, and every sampled series of its runs.
    page = httpx.get(f"{stack.url}/submissions/{l02['id']}", headers=_auth(stack, "alice"))
    assert page.status_code == 200 and "L02 CHECK: PASSED" in page.text and "L03 CHECK" not in page.text
    series = httpx.get(f"{stack.url}/v1/submissions/{l02['id']}/series", headers=_auth(stack, "alice"))
    assert series.status_code == 200, series.text
    runs = {run["name"]: run for run in series.json()["runs"]}
    assert set(runs["S1"]["series"]) == {"t", "z", "vz", "contact_count"} and len(runs["S2"]["series"]["z"]) == 120
    assert runs["S1"]["metrics"]["first_contact_t"] == pytest.approx(runs["S1"]["series"]["t"][
        runs["S1"]["series"]["contact_count"].index(next(c for c in runs["S1"]["series"]["contact_count"] if c)) ])


def test_a_student_answers_l02_from_the_page_in_chinese_and_reads_its_report(browser, course, assignments):
    """The L02 assignment's page, read in Chinese: its questions, a YAML imported, Check by L02's rule, submitted and
    graded on real runs; the report shows L02's check line and its conditions in Chinese."""
    stack = course
    page = signed_in(browser, stack, "bob")
    page.set_extra_http_headers({"Accept-Language": "zh-CN,zh;q=0.9"})
    page.goto(f"{stack.url}/assignments/{assignments['L02']}/sheet")
    assert page.locator("html").get_attribute("lang") == "zh"
    assert "盒子何时首次接触地面" in page.inner_text("#item-P3")
    page.set_input_files("#yaml-file", str(L02_YAML))
    page.click("#yaml button[type=submit]")
    page.wait_for_selector("#notice")
    assert page.is_checked("input[name='answers.P4.lower'][value='S1']")
    page.fill("[id='f-configs.exercise.substeps']", "4")  # the exercise may change its timing: one factor still
    page.fill("[id='f-answers.E1.internal_updates']", "600")
    page.click("button[value=check]")
    page.wait_for_selector("#one-factor")
    assert "one-factor violation" not in page.inner_text("#one-factor")
    page.screenshot(path=SHOTS / "l02_sheet_form_zh.png", full_page=True)
    page.click("button[value=submit]")
    page.click("#confirm-submit")
    page.wait_for_url(f"{stack.url}/submissions/*/progress")
    submission = int(page.url.split("/")[-2])
    client = stack.client("bob")
    final = client.wait(submission, poll_s=0.5, timeout_s=WAIT_LIMIT_S)
    assert final["status"] == "graded", final
    wait_until(lambda: client.grade(submission)["check"] is not None, "the lab check")
    grade = client.grade(submission)
    assert grade["total"] == grade["max_total"] == 22, [(i["id"], i["verdict"]) for i in grade["items"]]
    page.goto(f"{stack.url}/submissions/{submission}")
    page.wait_for_selector("#lab-check")
    assert page.locator("#check-line code").inner_text() == "L02 CHECK: PASSED"
    assert "盒子在自由落体预测的时刻接触地面" in page.inner_text("#lab-check")
    # L02's own charts (lessons/l02/lesson.py CHARTS), titled in its Chinese words, each drawn over its three runs
    charts_drawn(page)
    assert [page.locator(f"#caption-series-drop-{c} strong").inner_text() for c in ("z", "vz", "contact")] == [
        "盒子中心高度 z（每次运行）.", "盒子竖直速度 vz（每次运行）.", "盒子与地面的接触数（每次运行）."]
    assert page.locator("#figures .chart").evaluate_all("els => els.map(e => e.getAttribute('data-series'))") == [
        "3", "3", "3"]
    assert "S2 (dt=0.005 s, substeps=2): z(0.30 s) = 0.5" in page.inner_text("#caption-series-drop-z")
    page.screenshot(path=SHOTS / "l02_report_zh.png", full_page=True)

    # The instructor's dashboard in Chinese: each lesson's item analysis, its questions in its own lesson's words.
    prof = signed_in(browser, stack, "prof")
    prof.set_extra_http_headers({"Accept-Language": "zh-CN,zh;q=0.9"})
    prof.goto(f"{stack.url}/courses/{COURSE}/dashboard")
    prof.wait_for_selector("#item-analysis-L02")
    assert "在 0.6 s 内，S1（dt 0.01 s）和 S2（dt 0.005 s）各记录多少个采样" in prof.inner_text("#analysis-L02-C1")
    assert prof.locator("#analysis-L03-C1").count() == prof.locator("#item-analysis-L03").count()  # its own row
    assert_accessible(prof, "the dashboard of a course with two lessons")
    prof.locator("#item-analysis-title").scroll_into_view_if_needed()
    prof.screenshot(path=SHOTS / "dashboard_two_lessons_zh.png", full_page=True)
