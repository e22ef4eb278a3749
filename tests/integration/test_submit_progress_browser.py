"""The whole walk of a student in a real browser (Debian's chromium driven by Playwright) over the real stack
(PostgreSQL, Redis, a Celery worker running Genesis): signed in by a link, the assignment's form filled (a YAML
imported, the table friction changed in the form), the confirmation read (attempt, lateness, penalty), the attempt
submitted, its case runs followed live on the progress page (states change with no reload), then the report. The
stored grade equals what `grader grade` gives for the YAML the form exported. Screenshots of the confirmation and the
progress page, desktop and phone width, under /tmp/shots/submit/ (or $SUBMIT_SHOTS_DIR)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import pytest
import yaml
from sqlalchemy import select
from sqlalchemy.orm import Session

from grader.client import Client
from grader.core.models import Grade
from tests.factories import ROOT, reference_sheet
from tests.integration.helpers import WAIT_LIMIT_S, at

pytestmark = [pytest.mark.integration, pytest.mark.slow]
SHOTS = Path(os.environ.get("SUBMIT_SHOTS_DIR", "/tmp/shots/submit"))
PHONE = {"width": 390, "height": 844}
DESKTOP = {"width": 1280, "height": 900}
# A colour no other test gives the extension's cube: visual only for the one-factor rule, but part of the content
# key, so this walk's configs are run by the worker while the page watches, never reused from an earlier test.
OWN_COLOR = [0.25, 0.75, 0.5]


def shoot(page, name: str) -> None:
    """The page at desktop and at phone width."""
    SHOTS.mkdir(parents=True, exist_ok=True)
    page.screenshot(path=SHOTS / f"{name}.png", full_page=True)
    page.set_viewport_size(PHONE)
    page.screenshot(path=SHOTS / f"{name}_phone.png", full_page=True)
    page.set_viewport_size(DESKTOP)


def consumers(stack, command: str) -> None:
    """`celery control cancel_consumer|add_consumer cpu` on the stack's broker: its worker stops or starts taking case
    runs (what it runs meanwhile finishes; queued runs wait in the broker)."""
    done = subprocess.run([sys.executable, "-m", "celery", "-A", "worker.celery_app", "control", command, "cpu"],
                          cwd=ROOT, env=stack.env, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0 and "OK" in done.stdout, done.stdout + done.stderr


def states(page) -> dict[str, str]:
    """Each case run's state as the page shows it now."""
    rows = page.locator("#runs tbody tr")
    return {rows.nth(i).get_attribute("id").removeprefix("run-"):
            rows.nth(i).locator("[data-state]").get_attribute("data-state") for i in range(rows.count())}


def watch(page, report_path: str) -> list[dict[str, str]]:
    """The states the progress page shows, read until its script moves it to the report; asserts the page was not
    reloaded meanwhile (a mark set on its window stays)."""
    page.evaluate("window.progressMark = 'kept'")
    seen: list[dict[str, str]] = []
    deadline = time.monotonic() + WAIT_LIMIT_S
    while not page.url.endswith(report_path):
        assert time.monotonic() < deadline, f"the page never moved to the report; it showed {seen[-1:]}"
        try:
            now = states(page)
            if page.evaluate("window.progressMark") != "kept":  # a new document: the report, or a reload
                assert page.url.endswith(report_path), "the progress page reloaded"
                break
            if not seen or now != seen[-1]:
                seen.append(now)
                if "done" in now.values() and not (SHOTS / "progress_running.png").exists():
                    page.screenshot(path=SHOTS / "progress_running.png", full_page=True)  # part done, part waiting
        except AssertionError:
            raise
        except Exception:  # noqa: BLE001 - the script began to navigate between two reads: only to the report
            page.wait_for_url(f"**{report_path}", timeout=30_000)
            break
        time.sleep(0.25)
    return seen


def test_a_student_submits_from_the_form_follows_the_runs_and_reads_the_report(browser, stack, tmp_path):
    prof = stack.client("prof")
    course = "l03-test"
    (ada,) = prof.import_roster(course, "student_id,name,email\ns3001,Ada Walk,ada.walk@example.edu\n", links=True)
    sheet_assignment = prof.create_assignment(course, {
        "title": "L03 sheet", "part": "sheet", "open_at": at(days=-3), "due_at": at(hours=-2, minutes=-10),
        "hard_close_at": at(days=2), "late_penalty_per_day": 0.1, "max_attempts": 2})
    aid = sheet_assignment["id"]
    sheet = reference_sheet() | {"student": "s3001"}
    sheet["configs"]["extension"]["cube"] = {"color": OWN_COLOR}
    (tmp_path / "mine.yaml").write_text(yaml.safe_dump(sheet, sort_keys=False))

    context = browser.new_context(viewport=DESKTOP)
    page = context.new_page()
    page.goto(ada["sign_in_link"])
    page.click("main form button[type=submit]")
    page.wait_for_url(f"{stack.url}/courses/{course}")
    page.click(f"a[href='/assignments/{aid}/sheet']")
    page.wait_for_url(f"{stack.url}/assignments/{aid}/sheet")
    page.set_input_files("#yaml-file", str(tmp_path / "mine.yaml"))
    page.click("#yaml button[type=submit]")
    page.wait_for_selector("#notice")
    page.fill("[id='f-configs.table_exercise.table.friction']", "0.35")  # the one factor this exercise may change
    with page.expect_download() as download:
        page.click("button[value=export]")
    exported = tmp_path / "exported.yaml"
    exported.write_text(Path(download.value.path()).read_text())
    assert yaml.safe_load(exported.read_text())["configs"]["table_exercise"]["table"]["friction"] == 0.35
    # `grader grade` of the same YAML runs its cases on this machine while the service grades the submission.
    cli = subprocess.Popen([sys.executable, "-m", "grader.cli", "grade", str(exported), "--out", str(tmp_path / "cli"),
                            "--json"], cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)

    page.click("button[value=submit]")
    page.wait_for_selector("#confirm")
    assert page.inner_text("h1") == "Submit attempt 1 of L03 sheet?"
    assert page.inner_text("#confirm-attempt") == "attempt 1 of 2 (1 left after this one)"
    late = page.inner_text("#confirm-late")
    assert late.startswith("2 h 1") and "(1 day charged)" in late
    assert page.inner_text("#confirm-penalty") == "10% of this attempt's score is taken"
    shoot(page, "confirmation")
    # The worker stops taking case runs until the page has shown this sheet's runs waiting: with two warm case slots
    # the two runs may finish within a second, before a loaded machine has drawn the page (seen once in a run a year
    # ahead). The runs are then measured as any others, once the worker consumes its queue again.
    consumers(stack, "cancel_consumer")
    try:
        page.click("#confirm-submit")
        page.wait_for_url(f"{stack.url}/submissions/*/progress")
        submission_id = int(page.url.split("/")[-2])
        page.wait_for_selector("#runs")
        first = states(page)
    finally:
        consumers(stack, "add_consumer")
    (SHOTS / "progress_running.png").unlink(missing_ok=True)
    shoot(page, "progress")
    seen = [first, *watch(page, f"/submissions/{submission_id}")]

    # The configs' runs were seen waiting or running, then done, on the one page load.
    for run in ("sheet.table_exercise", "sheet.extension"):
        shown = [s.get(run) for s in seen]
        assert shown[0] in ("queued", "running") and "done" in shown, (run, seen)
    page.wait_for_selector("#items")
    stored = Client(stack.url, ada["token"]).submission(submission_id)
    assert stored["status"] == "graded" and stored["attempt"] == 1 and stored["penalty"] == 0.1, stored

    out, err = cli.communicate(timeout=WAIT_LIMIT_S)
    assert cli.returncode == 0, err[-3000:]
    local = json.loads(out)
    with Session(stack.engine) as session:
        grade = session.scalar(select(Grade).where(Grade.submission_id == submission_id, Grade.superseded_at.is_(None)))
        report = grade.report
    assert grade.total == local["total"] and grade.max_total == local["max_total"]
    assert {i["id"]: (i["verdict"], i["score"]) for i in report["items"]} == \
        {i["id"]: (i["verdict"], i["score"]) for i in local["items"]}
    context.close()
