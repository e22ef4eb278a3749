"""Shared steps of the integration tests: submit over HTTP, wait, read the database directly."""

from __future__ import annotations

import os
import time
from pathlib import Path

from sqlalchemy import func, select
from sqlalchemy.orm import Session

from grader.models import CaseRun, Event, Grade
from tests.factories import ROOT

# Safety stop only (a cold kernel cache can take minutes); no test asserts how long anything took.
WAIT_LIMIT_S = 900


def submit_and_wait(stack, sheet: dict, who: str = "alice", **options) -> tuple[dict, dict]:
    client = stack.client(who)
    created = client.submit(sheet, **options)
    final = client.wait(created["id"], poll_s=0.5, timeout_s=WAIT_LIMIT_S)
    return created, final


def wait_until(predicate, what: str, limit_s: float = WAIT_LIMIT_S):
    deadline = time.monotonic() + limit_s
    while not (value := predicate()):
        if time.monotonic() > deadline:
            raise AssertionError(f"gave up waiting for {what}")
        time.sleep(0.2)
    return value


def images_decoded(page, selector: str) -> None:
    """Wait until every image `selector` matches is decoded, none broken. Polled from here, not with
    page.wait_for_function: that evaluates a string in the page, which the pages' CSP (no 'unsafe-eval') refuses."""
    wait_until(lambda: all(page.locator(selector).evaluate_all("els => els.map(i => i.complete && i.naturalWidth > 0)")),
               f"every {selector} decoded")


def grades_of(stack, submission_id: int) -> int:
    with Session(stack.engine) as session:
        return session.scalar(select(func.count()).select_from(Grade).where(Grade.submission_id == submission_id))


def case_runs(stack, submission_id: int) -> list[CaseRun]:
    with Session(stack.engine) as session:
        return session.scalars(select(CaseRun).where(CaseRun.submission_id == submission_id)
                               .order_by(CaseRun.id)).all()


def events(stack, submission_id: int) -> list[Event]:
    with Session(stack.engine) as session:
        return session.scalars(select(Event).where(Event.submission_id == submission_id).order_by(Event.id)).all()


CHROMIUM = Path("/usr/bin/chromium")
SHOTS = Path(os.environ.get("SCREENSHOTS_DIR", ROOT / "out" / "screenshots"))


def signed_in(browser, stack, who: str, *, width: int = 1280):
    """A new browser page signed in through the sign-in form with `who`'s token."""
    page = browser.new_page(viewport={"width": width, "height": 900})
    page.goto(f"{stack.url}/submissions")
    assert page.url.startswith(f"{stack.url}/sign-in")
    page.fill("#token", stack.tokens[who])
    page.click("button[type=submit]")
    return page
