"""The tolerance review in a real browser over the real stack (API over HTTP, a Celery worker, PostgreSQL, real
Genesis runs): a student's N1 measured for real and a 64-bit twin of it whose heights sit 0.8 mm lower, compared by
the worker's own audit; the review page flags the tolerances that difference exceeds and links the entry; an
instructor signs the version off, drafts a new version (refused without a new rationale), publishes it, previews the
regrade (which names the tolerance change behind each changed item) and commits it. Its own course, so the other
page tests' class keeps its grades. Screenshots in review/ under the other browser tests' folder (out/screenshots/ or $SCREENSHOTS_DIR)."""

from __future__ import annotations

import re

import pytest
from sqlalchemy import select
from sqlalchemy.orm import Session

from grader.core.models import CaseRun, Course, RubricVersion, User
from tests.factories import reference_sheet
from tests.grader.services.rubrics.test_tolerance_review import precision_twin
from tests.integration.helpers import SHOTS as ALL_SHOTS, submit_and_wait
from tests.integration.layout import assert_fits, pages_in_both_languages

pytestmark = [pytest.mark.integration, pytest.mark.slow]
COURSE = "review-class"
SHOTS = ALL_SHOTS / "review"
WIDER = "0.002"  # proxy_resolution 0.5 mm -> 2 mm: the proxy changes N1->N2 and N3->N4 (about 5 mm and 11 mm) stay
# resolved, so A2 keeps its verdict; X2 and X3 read the same tolerance on N1 -> N5 (about 1.3 mm), which becomes
# unresolved, so their verdicts can change


@pytest.fixture(scope="module")
def review_class(stack):
    """Pia's reference sheet graded for real in a course of her own, with instructor Ivan and auditor Aude."""
    from grader.services.identity import accounts

    with Session(stack.engine) as session:
        course = accounts.get_or_create_course(session=session, name=COURSE)
        course.timezone = "Asia/Kolkata"  # a half-hour zone: every time on these pages is in it, none in UTC
        for name, role in (("pia", "student"), ("ivan", "instructor"), ("aude", "auditor")):
            user = accounts.get_or_create_user(session=session, course=course, name=name, role=role)
            stack.tokens[name] = accounts.create_token(session=session, user=user)
        session.commit()
    _, final = submit_and_wait(stack, reference_sheet() | {"student": "pia"}, who="pia")
    assert final["status"] == "graded", final
    return final["id"]


def _precision_twin(stack, submission_id: int) -> int:
    """A 64-bit audit re-run of Pia's N1 whose stored measurement is her real one 0.8 mm lower, compared by the
    worker's audit (worker.audit.audit_finished_run) in the stack's database; the entry's id."""
    from grader.core.lifecycle import stored_result

    with Session(stack.engine) as session:
        run = session.scalar(select(CaseRun).where(CaseRun.submission_id == submission_id, CaseRun.name == "N1"))
        entries = precision_twin(session, run, stored_result(run),
                                 session.scalar(select(User).join(Course).where(User.name == "aude",
                                                                                 Course.name == COURSE)))
        assert len(entries) == 1 and entries[0].right_variant.startswith("cpu/64/"), entries
        return entries[0].id


def _signed_in(browser, stack, who: str, *, width: int = 1280, locale: str = "en"):
    """A page signed in through the sign-in form, waiting until the sign-in has landed (a goto right after the click
    would abort its POST); the sign-in form's own button, as the header may hold other forms (the language switch)."""
    page = browser.new_page(viewport={"width": width, "height": 900}, locale=locale)
    page.goto(f"{stack.url}/submissions")
    assert page.url.startswith(f"{stack.url}/sign-in")
    page.fill("#token", stack.tokens[who])
    page.click("form[action='/sign-in'] button[type=submit]")
    page.wait_for_selector("header .who")
    return page


def _hash(stack, version: str) -> str:
    with Session(stack.engine) as session:
        return session.scalar(select(RubricVersion.content_hash).where(RubricVersion.lesson == "L03",
                                                                       RubricVersion.version == version,
                                                                       RubricVersion.course_id.is_(None)))


def test_an_instructor_reviews_signs_off_drafts_and_regrades_in_the_browser(browser, stack, review_class):
    SHOTS.mkdir(parents=True, exist_ok=True)
    entry = _precision_twin(stack, review_class)
    page = _signed_in(browser, stack, "ivan")
    page.goto(f"{stack.url}/courses/{COURSE}/rubrics")
    assert page.inner_text("#signoff-2").strip() == "not signed off yet"
    page.click("#review-link-2")
    page.wait_for_selector("#tolerances")
    assert "Instructor sign-off pending." in page.inner_text("#signoff-state")
    proxy = page.locator("#tol-proxy_resolution")
    assert "FLAGGED" in proxy.inner_text() and f"audit entry {entry}" in proxy.inner_text()
    assert "FLAGGED" in page.inner_text("#tol-n1_n4_max_dz")
    assert "FLAGGED" not in page.inner_text("#tol-pair_friction_abs")
    assert page.inner_text("#flag-summary").startswith("2 tolerance(s) flagged")
    # the source names what its date is: when this service first stored a shipped version, not a publication
    assert re.fullmatch(r"shipped with the service; first stored by this service \d{4}-\d\d-\d\d \d\d:\d\d IST "
                        r"\(not when it was written\)", page.inner_text("#version-source")), \
        page.inner_text("#version-source")
    assert "sign-off pending" in page.inner_text("#review-record")  # the shipped record says so while it is true
    assert_fits(page, "tolerance review at 1280 px")  # no horizontal scroll, no word broken inside a cell
    page.screenshot(path=str(SHOTS / "review-flagged.png"), full_page=True)
    hash_before = _hash(stack, "2")

    # the flag's link is the audit entry that shows it
    proxy.locator(f"a[href='/audit/{entry}']").first.click()
    page.wait_for_load_state()
    assert page.url.endswith(f"/audit/{entry}") and "cpu/64" in page.inner_text("main")
    page.go_back()

    page.fill("#signoff-note", "Flags read: the 64-bit twin is a crafted test pair")
    page.click("#signoff-form button[type=submit]")
    page.wait_for_selector("#signoff-state.info")
    # in the course's zone, as the set-up page promises
    assert re.search(r"by ivan, \d{4}-\d\d-\d\d \d\d:\d\d IST: Flags read", page.inner_text("#signoff-state"))
    assert page.locator("#signoff-form").count() == 0  # signed once
    # one sign-off status: the shipped record's "instructor sign-off pending" is gone once it is signed off
    assert "sign-off pending" not in page.inner_text("main").lower()
    assert page.inner_text("#review-record").startswith("rubric v2 author (measured-items revision), ")
    page.screenshot(path=str(SHOTS / "review-signed-off.png"), full_page=True)
    pages_in_both_languages(browser, lambda b, **kw: _signed_in(b, stack, "ivan", **kw),
                            f"{stack.url}/courses/{COURSE}/rubrics/L03/2", SHOTS, "tolerance-review",
                            ready="#tolerances")
    pages_in_both_languages(browser, lambda b, **kw: _signed_in(b, stack, "ivan", **kw),
                            f"{stack.url}/courses/{COURSE}/rubrics", SHOTS, "rubrics", ready="#versions")
    assert _hash(stack, "2") == hash_before  # signing never changes the version
    page.goto(f"{stack.url}/courses/{COURSE}/rubrics")
    assert re.match(r"signed off by ivan, \d{4}-\d\d-\d\d \d\d:\d\d IST", page.inner_text("#signoff-2"))
    assert "pending" not in page.inner_text("#version-2")
    page.screenshot(path=str(SHOTS / "rubrics-list.png"), full_page=True)

    # the auditor reads the review but neither signs nor drafts
    aude = _signed_in(browser, stack, "aude")
    aude.goto(f"{stack.url}/courses/{COURSE}/rubrics/L03/2")
    assert "FLAGGED" in aude.inner_text("#tol-proxy_resolution") and aude.locator("#signoff-form").count() == 0
    assert aude.locator("#draft-link").count() == 0

    page.goto(f"{stack.url}/courses/{COURSE}/rubrics/L03/2")
    page.click("#draft-link")
    page.wait_for_selector("#draft-form")
    assert page.input_value("#draft-version") == "3" and page.input_value("#value-proxy_resolution") == "0.0005"
    page.fill("#value-proxy_resolution", WIDER)
    page.fill("#draft-notes", "proxy_resolution widened after the tolerance review")
    page.click("#publish")
    page.wait_for_selector("#error-proxy_resolution-rationale")
    assert "a changed tolerance needs a new rationale" in page.inner_text("#error-proxy_resolution-rationale")
    assert page.input_value("#value-proxy_resolution") == WIDER  # what was typed is kept
    page.locator("#draft-proxy_resolution").scroll_into_view_if_needed()
    page.screenshot(path=str(SHOTS / "draft-refused.png"), full_page=True)

    page.fill("#rationale-proxy_resolution", "Widened to 2 mm after the tolerance review: four times the 0.5 mm it "
                                             "replaces, so a precision difference of 0.8 mm cannot flip a direction")
    page.click("#publish")
    page.wait_for_selector("#preview")
    assert page.url.endswith(f"/courses/{COURSE}/regrade?version=3&lesson=L03")
    assert "tolerances.proxy_resolution: 0.0005 m -> 0.002 m" in page.inner_text("main")
    row = page.locator(f"#preview-{review_class}")
    changes = row.locator(".change")
    for i in range(changes.count()):  # every changed item names the tolerance change behind it
        assert "tolerance proxy_resolution: 0.0005 m -> 0.002 m" in changes.nth(i).inner_text()
    page.screenshot(path=str(SHOTS / "regrade-preview.png"), full_page=True)
    page.click("#commit button[type=submit]")
    page.wait_for_selector("#regrades")
    assert page.inner_text("#current-version") == "v3"
    assert page.inner_text("#signoff-3").strip() == "not signed off yet"  # a new version's sign-off starts pending
    page.screenshot(path=str(SHOTS / "rubrics-after-commit.png"), full_page=True)
