"""The course set-up pages in a real browser (Debian's chromium driven by Playwright) over the API on loopback with
PostgreSQL (issue 23, item 1): an instructor sets the zone, creates an assignment (a refused try first), uploads a
roster and downloads the tokens and links it shows once, grants an extension and releases the hidden items, all from
the pages; the API shows the same state, and the student's token from that download is what the API admits her by.
Nothing here is graded, so no worker runs and no case is measured. Screenshots land in $SCREENSHOTS_DIR (or
out/screenshots/)."""

from __future__ import annotations

from datetime import UTC, datetime, timedelta
from pathlib import Path
from zoneinfo import ZoneInfo

import httpx
import pytest

from grader.core import clock
from tests.grader.services.setup.test_assignments import checkpoint_sheet
from tests.integration.helpers import SHOTS, measured_course_api
from tests.integration.layout import assert_fits, pages_in_both_languages

pytestmark = pytest.mark.integration
COURSE = "l03-setup"
ZONE = "Europe/Berlin"


@pytest.fixture(scope="module")
def api(tmp_path_factory):
    """The API alone (uvicorn) on a fresh PostgreSQL database with the people of tests.factories; nothing is ever
    enqueued here."""
    with measured_course_api(tmp_path_factory.mktemp("setup-pages"), None, course=COURSE) as running:
        yield running


def sign_in(browser, api, who: str, *, locale: str = "en", width: int = 1280):
    """A new page signed in through the sign-in form (its own button: the header has the language buttons too)."""
    page = browser.new_page(viewport={"width": width, "height": 900}, locale=locale)
    page.goto(f"{api.url}/submissions")
    page.fill("#token", api.tokens[who])
    page.click("main button[type=submit]")
    page.wait_for_selector("header .who")
    return page


def berlin(**delta) -> str:
    """Now plus `delta`, as a datetime-local value in the course's zone (whole minutes)."""
    return (clock.now().replace(tzinfo=UTC) + timedelta(**delta)).astimezone(ZoneInfo(ZONE)).strftime("%Y-%m-%dT%H:%M")


def utc(local: str) -> str:
    return datetime.fromisoformat(local).replace(tzinfo=ZoneInfo(ZONE)).astimezone(UTC).strftime("%Y-%m-%dT%H:%M:%SZ")


def shot(page, name: str) -> None:
    for folder in (SHOTS, Path("/tmp/shots/setup")):
        folder.mkdir(parents=True, exist_ok=True)
        page.screenshot(path=str(folder / name), full_page=True)


def test_an_instructor_sets_up_the_course_from_the_pages_and_the_api_shows_it(browser, api, tmp_path):
    prof = api.client("prof")
    prof_http = {"Authorization": f"Bearer {api.tokens['prof']}"}
    httpx.post(f"{api.url}/v1/courses/{COURSE}/lti/registrations", headers=prof_http, json={
        "issuer": "https://canvas.example.edu", "client_id": "10000000000042", "deployment_ids": ["7:abc", "8:def"],
        "auth_login_url": "https://canvas.example.edu/api/lti/authorize_redirect",
        "auth_token_url": "https://canvas.example.edu/login/oauth2/token",
        "key_set_url": "https://canvas.example.edu/api/lti/security/jwks"}).raise_for_status()
    page = sign_in(browser, api, "prof")
    page.click("text=Course set-up")
    page.wait_for_selector("#timezone")
    assert "10000000000042" in page.inner_text("#registrations") and "7:abc" in page.inner_text("#registrations")

    # The zone, by its label.
    page.get_by_label("IANA time zone name").fill(ZONE)
    page.click("text=Set the time zone")
    page.wait_for_selector("#changes")
    assert prof.course(COURSE)["timezone"] == ZONE

    # A new assignment: first refused (due before it opens), the values kept and the error beside the field.
    page.click("#new-assignment")
    page.wait_for_selector("#assignment-form")
    opens, due, close = berlin(days=-3), berlin(days=-2), berlin(days=-1)
    page.get_by_label("Title").fill("Week 3 checkpoints")
    page.select_option("#f-part", "checkpoints")
    page.fill("#f-open_at", opens)
    page.fill("#f-due_at", berlin(days=-4))
    page.fill("#f-hard_close_at", close)
    page.fill("#f-late_penalty_per_day", "0.1")
    page.fill("#f-max_attempts", "3")
    page.select_option("#f-counted_attempt", "best")
    page.select_option("#f-item_visibility-C3", "on_release")
    # the per-item list holds the chosen part's items only: the checkpoints, not the 18 other items of the sheet
    shown = [r for r in page.locator("#item-visibility tbody tr").all() if r.is_visible()]
    assert [r.get_attribute("id") for r in shown] == [f"row-C{i}" for i in range(1, 9)]
    page.select_option("#f-part", "sheet")
    assert page.locator("#row-A2").is_visible() and page.locator("#row-C3").is_visible()
    page.select_option("#f-part", "checkpoints")
    assert not page.locator("#row-A2").is_visible()
    page.click("#save")
    page.wait_for_selector("#form-errors")
    # errors name fields by the form's labels, never by the API's names
    assert "“Due” must be after “Opens”" in page.inner_text("#e-due_at")
    assert page.inner_text("#form-errors li").startswith("Due: “Due” must be after “Opens”")
    assert "due_at" not in page.inner_text("#form-errors") and "open_at" not in page.inner_text("#form-errors")
    assert page.input_value("#f-title") == "Week 3 checkpoints"
    assert page.input_value("#f-item_visibility-C3") == "on_release"
    assert prof.assignments(COURSE) == []
    shot(page, "setup-assignment-form-refused.png")
    page.fill("#f-due_at", due)
    page.click("#save")
    page.wait_for_selector("#students")
    (row,) = prof.assignments(COURSE)
    aid = row["id"]
    assert page.url.endswith(f"/assignments/{aid}")
    assert (row["title"], row["part"], row["late_penalty_per_day"], row["max_attempts"], row["counted_attempt"],
            row["item_visibility"]) == ("Week 3 checkpoints", "checkpoints", 0.1, 3, "best", {"C3": "on_release"})
    assert (row["open_at"], row["due_at"], row["hard_close_at"]) == (utc(opens), utc(due), utc(close))

    # The roster, with sign-in links: shown once, and downloaded as CSV.
    page.click("text=Course set-up")
    roster = tmp_path / "roster.csv"
    roster.write_text("student_id,name,email\ns1001,Ada Lovelace,ada@example.edu\ns1002,Alan Turing,alan@example.edu\n")
    page.set_input_files("#f-csv", str(roster))
    page.check("#f-links")
    page.click("text=Upload and import")
    page.wait_for_selector("#issued")
    assert "2 new student(s), 0 updated." in page.inner_text("#import-summary")
    with page.expect_download() as download:
        page.click("#download")
    issued = Path(download.value.path()).read_text().splitlines()
    assert issued[0] == "student_id,name,email,token,sign_in_link"
    ada = dict(zip(issued[0].split(","), next(line for line in issued if line.startswith("s1001,")).split(",")))
    assert ada["token"] in page.inner_text("#issued-s1001")
    assert ada["sign_in_link"].startswith(f"{api.url}/sign-in/link/")
    shot(page, "setup-roster-issued.png")
    page.goto(f"{api.url}/courses/{COURSE}/setup")  # the set-up page again: the tokens are nowhere on it
    page.wait_for_selector("#student-s1001")
    assert ada["token"] not in page.content()

    # An extension for s1001 and the release, from the assignment's page.
    page.goto(f"{api.url}/assignments/{aid}")
    ext_due, ext_close = berlin(hours=-3), berlin(hours=-2)
    page.select_option("#f-ext-student", "s1001")
    page.fill("#f-ext-due", ext_due)
    page.fill("#f-ext-close", ext_close)
    page.click("#grant")
    page.wait_for_selector("#extension-s1001")
    assert "by prof" in page.inner_text("#extension-s1001")
    shot(page, "setup-assignment-page-before-release.png")
    page.click("#release")
    page.wait_for_selector("#extensions")
    assert page.locator("#release").count() == 0 and "released" in page.inner_text("#settings")
    shot(page, "setup-assignment-page.png")

    # The API shows the same state: released, and s1001 (by the token from the download) held to her extension.
    assert prof.assignment(aid)["released_at"] is not None
    refused = httpx.post(f"{api.url}/v1/submissions", headers={"Authorization": f"Bearer {ada['token']}"},
                         json={"sheet": checkpoint_sheet("s1001"), "assignment_id": aid})
    rule = refused.json()["errors"][0]["rule"]
    assert refused.status_code == 409 and "your extension's hard close" in rule
    assert ext_close in rule  # in the course's zone
    bob = httpx.post(f"{api.url}/v1/submissions", headers={"Authorization": f"Bearer {api.tokens['bob']}"},
                     json={"sheet": checkpoint_sheet("bob"), "assignment_id": aid})
    assert bob.status_code == 409 and "(its hard close)" in bob.json()["errors"][0]["rule"]

    # Submissions outside assignments: refused from the set-up page, recorded like the other settings.
    page.goto(f"{api.url}/courses/{COURSE}/setup")
    assert page.is_checked("#f-free") and page.inner_text("#free-submissions-state").startswith("Allowed")
    page.uncheck("#f-free")
    page.click("#free-submissions button[type=submit]")
    page.wait_for_selector("#free-submissions-state")
    assert page.inner_text("#free-submissions-state").startswith("Refused") and not page.is_checked("#f-free")
    assert prof.course(COURSE)["free_submissions"] is False

    # Every change, with who, on the set-up page.
    page.goto(f"{api.url}/courses/{COURSE}/setup")
    changes = page.inner_text("#changes")
    for what in ("time zone UTC → Europe/Berlin", f"created assignment {aid}", "roster imported: 2 new",
                 "extension for s1001", f"released assignment {aid}", "submissions outside assignments allowed → "
                 "refused"):
        assert what in changes, what
    assert "prof" in changes
    assert_fits(page, "set-up page at 1280 px")  # it was 1376 px wide with its assignments' dates on one line
    shot(page, "setup-page.png")
    # The API lists what the page shows: the roster, the assignment's extensions and the change log (staff only).
    roster_rows = httpx.get(f"{api.url}/v1/courses/{COURSE}/roster", headers=prof_http).json()
    assert {"student": "s1001", "name": "Ada Lovelace", "email": "ada@example.edu"} in roster_rows
    (ext,) = httpx.get(f"{api.url}/v1/assignments/{aid}/extensions", headers=prof_http).json()
    assert (ext["student"], ext["granted_by"], ext["due_at"]) == ("s1001", "prof", utc(ext_due))
    logged = httpx.get(f"{api.url}/v1/courses/{COURSE}/changes", headers=prof_http).json()
    assert logged[0]["kind"] == "course_settings" and logged[0]["detail"] == {"free_submissions": [True, False]}
    assert len(logged) >= 6 and {c["by"] for c in logged} == {"prof"}
    for url, name, ready in ((f"{api.url}/courses/{COURSE}/setup", "setup-page", "#changes"),
                             (f"{api.url}/assignments/{aid}/edit", "setup-assignment-form", "#assignment-form")):
        pages_in_both_languages(browser, lambda b, **kw: sign_in(b, api, "prof", **kw), url, SHOTS, name,
                                ready=ready)
    page.goto(f"{api.url}/assignments/{aid}/edit")
    page.wait_for_selector("#assignment-form")
    assert page.input_value("#f-due_at") == due
    shot(page, "setup-assignment-edit.png")
    page.close()

    # A teaching assistant asking for the set-up page gets the 404 page.
    tess = sign_in(browser, api, "tess")
    tess.goto(f"{api.url}/courses/{COURSE}/setup")
    assert "Upload and import" not in tess.content() and tess.locator("text=Course set-up").count() == 0
    tess.close()
