"""Shared steps of the integration tests: submit over HTTP, wait, read the database directly."""

from __future__ import annotations

import os
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from datetime import UTC, timedelta
from pathlib import Path

from sqlalchemy import func, select
from sqlalchemy.orm import Session

from grader.core import clock
from grader.core.models import CaseRun, Event, Grade, Submission, VariantPool
from grader.core.states import CaseRunState, PoolState, SubmissionState
from tests import services
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


def backlog(engine) -> dict[str, int]:
    """The work a stack still owes, by kind (only kinds with some): case runs queued or running, submissions not yet
    graded or failed, grades whose lab check is not stored yet, variant pools still measuring. Each lab check waits on
    the cpu queue behind every case run (worker.celery_app), so a module that leaves runs behind delays the next
    module's checks by as long as they take."""
    with Session(engine) as session:
        counts = {
            "case runs queued or running": session.scalar(select(func.count()).select_from(CaseRun).where(
                CaseRun.status.in_([CaseRunState.QUEUED, CaseRunState.RUNNING]))),
            "submissions running or grading": session.scalar(select(func.count()).select_from(Submission).where(
                Submission.status.in_([SubmissionState.RUNNING, SubmissionState.GRADING]))),
            "grades without their lab check": session.scalar(select(func.count()).select_from(Grade).where(
                Grade.completed_at.is_(None), Grade.superseded_at.is_(None))),
            "variant pools measuring": session.scalar(select(func.count()).select_from(VariantPool).where(
                VariantPool.state == PoolState.MEASURING)),
        }
    return {kind: n for kind, n in counts.items() if n}


CHROMIUM = Path("/usr/bin/chromium")
SHOTS = Path(os.environ.get("SCREENSHOTS_DIR", ROOT / "out" / "screenshots"))


def signed_in(browser, stack, who: str, *, width: int = 1280):
    """A new browser page signed in through the sign-in form with `who`'s token."""
    page = browser.new_page(viewport={"width": width, "height": 900})
    page.goto(f"{stack.url}/submissions")
    assert page.url.startswith(f"{stack.url}/sign-in")
    page.fill("#token", stack.tokens[who])
    page.click("form[action='/sign-in'] button[type=submit]")  # not the header's language buttons
    return page


@dataclass
class MeasuredCourseApi:
    """The API alone (uvicorn) over a fresh PostgreSQL database whose course's lesson cases are stored as really
    measured: checkpoint sheets are graded in the request, and no worker is needed."""

    url: str
    tokens: dict[str, str]

    def client(self, who: str, token: str | None = None):
        from grader.client import Client

        return Client(self.url, token or self.tokens[who])


@contextmanager
def measured_course_api(folder: Path, measured, *, course: str) -> Iterator[MeasuredCourseApi]:
    """A MeasuredCourseApi for `course` (people of tests.factories.create_people), the lesson's runs stored from the
    session's `measured` results by another course's instructor (none stored when `measured` is None: nothing is
    ever graded there)."""
    from grader.core.db import make_engine, migrate
    from tests.factories import create_people, store_lesson_runs

    with services.postgres_database() as database_url:
        migrate(database_url)
        engine = make_engine(database_url)
        with Session(engine) as session:
            tokens = create_people(session, course=course, other_course="other-course")
            session.commit()
            if measured is not None:
                store_lesson_runs(session, measured, by="eve")
        engine.dispose()
        env = dict(os.environ, DATABASE_URL=database_url, BROKER_URL=services.REDIS_URL, DATA_DIR=str(folder),
                   PYTHONPATH=str(services.ROOT))
        port = services.free_port()
        proc = services.start_api(env, port, folder / "api.log")
        try:
            yield MeasuredCourseApi(f"http://127.0.0.1:{port}", tokens)
        finally:
            services.stop(proc)


def at(**delta) -> str:
    """The service's now (grader.core.clock) plus `delta` (timedelta's keywords), whole seconds, as RFC 3339 UTC."""
    return (clock.now().replace(microsecond=0, tzinfo=UTC) + timedelta(**delta)).isoformat()


def charts_drawn(page, selector: str = "#figures .chart[data-src]") -> None:
    """Wait until every browser chart `selector` matches is drawn (grader/static/report_charts.js records how many
    series it drew), none failed. Polled from here: page.wait_for_function is refused by the pages' CSP."""
    wait_until(lambda: all(page.locator(selector).evaluate_all("els => els.map(e => e.hasAttribute('data-series'))")),
               f"every {selector} drawn", limit_s=60)
    counts = page.locator(selector).evaluate_all("els => els.map(e => Number(e.getAttribute('data-series')))")
    assert counts and all(n > 0 for n in counts), counts
    assert page.locator("#figures .chart-failed").count() == 0
