"""The course set-up pages (issue 23, item 1) on the in-process app (SQLite): the time zone, creating and editing an
assignment with every setting the command line has, the roster upload whose tokens and links are shown once,
extensions and the release from the assignment page, the LMS registrations listed, and every change recorded with
who and when, by the services, so the API records too. Refusals follow the API's rules and messages, each beside its
field, nothing stored; anyone but the course's instructors gets the 404 page."""

from __future__ import annotations

import re
from urllib.parse import unquote

import pytest
from sqlalchemy import func, select

from grader.core.db import new_session
from grader.core.models import Assignment, CourseChange, Extension, User
from grader.pages.setup.courses import in_form_words
from tests.grader.services.setup.test_assignments import ROSTER, at, create, submit

# The forms below name days of December 2026 and January 2027: the clock stands before them on any calendar day.
pytestmark = [pytest.mark.clock("2026-11-20T12:00:00Z")]

BERLIN_FORM = {"title": "Week 3", "lesson": "L03", "part": "checkpoints", "open_at": "2026-12-01T10:00",
               "due_at": "2026-12-08T10:00", "hard_close_at": "2026-12-10T18:30", "late_penalty_per_day": "0.1",
               "late_penalty_cap": "0.3", "max_attempts": "3", "max_per_hour": "2", "counted_attempt": "best",
               "visibility": "after_due", "item_visibility.C3": "on_release"}


def page_post(api, path, data=None, who="prof", files=None, **headers):
    return api.client.post(path, data=data, files=files, headers={**api.as_(who), **headers}, follow_redirects=False)


def set_zone(api, zone="Europe/Berlin"):
    assert api.client.patch("/v1/courses/l03", json={"timezone": zone}, headers=api.as_("prof")).status_code == 200


def changes() -> list[tuple[str, str, str]]:
    with new_session() as session:
        return [(c.kind, c.by.name, c.summary) for c in session.scalars(select(CourseChange).order_by(CourseChange.id))]


def count(model) -> int:
    with new_session() as session:
        return session.scalar(select(func.count()).select_from(model))


def error_beside(text: str, field: str) -> str:
    """The error shown next to one field of the assignment form."""
    match = re.search(rf'<p class="field-error" id="e-{re.escape(field.replace(".", "-"))}">(.*?)</p>', text, re.S)
    assert match, f"no error beside {field}"
    return re.sub(r"<[^>]+>", "", match.group(1)).replace("&#39;", "'").replace("&#34;", '"')


# --- the page and who may see it ----------------------------------------------------------------------------------

def test_the_setup_page_shows_zone_assignments_roster_registrations_and_changes(api):
    create(api, title="Checkpoints week 3")
    api.client.post("/v1/courses/l03/lti/registrations", headers=api.as_("prof"), json={
        "issuer": "https://lms.example.edu", "client_id": "tool-17", "deployment_ids": ["d1", "d2"],
        "auth_login_url": "https://lms.example.edu/auth", "auth_token_url": "https://lms.example.edu/token",
        "key_set_url": "https://lms.example.edu/jwks"}).raise_for_status()
    page = api.client.get("/courses/l03/setup", headers=api.as_("prof"))
    assert page.status_code == 200, page.text
    text = page.text
    assert 'value="UTC"' in text and 'href="/courses/l03/setup/assignments/new"' in text
    assert "Checkpoints week 3" in text and 'id="student-alice"' in text and 'id="student-bob"' in text
    # long URLs carry <wbr> after their separators so that the table fits the page: the text read is without them
    registration = re.search(r'<tr id="registration-\d+">(.*?)</tr>', text, re.S).group(1).replace("<wbr>", "")
    for shown in ("https://lms.example.edu", "tool-17", "d1", "d2", "https://lms.example.edu/auth",
                  "https://lms.example.edu/token", "https://lms.example.edu/jwks"):
        assert shown in registration
    assert "grader lti register l03" in text and "/v1/courses/l03/lti/registrations" in text
    # The API's create was recorded by the service, with who.
    assert re.search(r'<td>prof</td>\s*<td>created assignment 1 &#39;Checkpoints week 3&#39;', text)
    assert 'href="/courses/l03/setup">Course set-up</a>' in text  # the instructor's nav link


@pytest.mark.parametrize("who", ["alice", "tess", "eve"])
def test_only_the_courses_instructors_see_or_change_the_setup(api, who):
    aid = create(api).json()["id"]
    before = changes()
    gets = ["/courses/l03/setup", "/courses/l03/setup/assignments/new", f"/assignments/{aid}/edit"]
    for path in gets:
        response = api.client.get(path, headers=api.as_(who))
        assert response.status_code == 404 and "Course set-up" not in response.text.split("<main>")[1], path
    posts = [("/courses/l03/setup/timezone", {"timezone": "Europe/Berlin"}),
             ("/courses/l03/setup/assignments", BERLIN_FORM), (f"/assignments/{aid}/edit", BERLIN_FORM),
             ("/courses/l03/setup/students/alice/sign-in-link", {}), (f"/assignments/{aid}/release", {}),
             (f"/assignments/{aid}/extensions", {"student": "bob", "due_at": "2026-12-09T10:00",
                                                 "hard_close_at": "2026-12-09T10:00"})]
    for path, data in posts:
        assert page_post(api, path, data, who=who).status_code == 404, path
    roster = page_post(api, "/courses/l03/setup/roster", {}, who=who,
                       files={"csv": ("r.csv", ROSTER.encode(), "text/csv")})
    assert roster.status_code == 404 and "s1001" not in roster.text
    assert changes() == before and count(Assignment) == 1 and count(Extension) == 0
    assert api.client.get("/v1/courses/l03", headers=api.as_("prof")).json()["timezone"] == "UTC"


def test_nobody_signed_in_is_sent_to_sign_in_and_another_site_cannot_post(api):
    response = api.client.get("/courses/l03/setup", follow_redirects=False)
    assert response.status_code == 303 and response.headers["location"].startswith("/sign-in?next=")
    forged = page_post(api, "/courses/l03/setup/timezone", {"timezone": "Europe/Berlin"},
                       **{"Sec-Fetch-Site": "cross-site"})
    assert forged.status_code == 403 and changes() == []


# --- the time zone ------------------------------------------------------------------------------------------------

def test_the_zone_is_set_from_the_page_and_recorded(api):
    response = page_post(api, "/courses/l03/setup/timezone", {"timezone": "Europe/Berlin"})
    assert response.status_code == 303 and response.headers["location"] == "/courses/l03/setup#timezone"
    assert api.client.get("/v1/courses/l03", headers=api.as_("alice")).json()["timezone"] == "Europe/Berlin"
    assert changes() == [("course_settings", "prof", "time zone UTC → Europe/Berlin")]
    page_post(api, "/courses/l03/setup/timezone", {"timezone": "Europe/Berlin"})
    assert len(changes()) == 1  # setting the same zone changes nothing and records nothing


def test_an_unknown_zone_is_refused_with_the_apis_message_beside_the_field_nothing_changed(api):
    api_rule = api.client.patch("/v1/courses/l03", json={"timezone": "Mars/Olympus"},
                                headers=api.as_("prof")).json()["errors"][0]["rule"]
    response = page_post(api, "/courses/l03/setup/timezone", {"timezone": "Mars/Olympus"})
    assert response.status_code == 422
    errors = re.search(r'id="timezone-errors">(.*?)</div>', response.text, re.S).group(1)
    assert "IANA time zone name: " in errors and api_rule.replace("'", "&#39;") in errors  # the field by its label
    assert 'value="Mars/Olympus"' in response.text and 'aria-invalid="true"' in response.text  # kept, marked
    assert api.client.get("/v1/courses/l03", headers=api.as_("prof")).json()["timezone"] == "UTC"
    assert changes() == []


# --- creating and editing an assignment ---------------------------------------------------------------------------

def test_an_assignment_created_from_the_form_in_the_courses_zone_is_what_the_api_shows(api):
    set_zone(api)
    form = api.client.get("/courses/l03/setup/assignments/new", headers=api.as_("prof"))
    assert form.status_code == 200 and "times in Europe/Berlin" in form.text
    for name in ("title", "part", "open_at", "due_at", "hard_close_at", "late_penalty_per_day", "late_penalty_cap",
                 "max_attempts", "max_per_hour", "counted_attempt", "visibility", "item_visibility.C3"):
        field_id = "f-" + name.replace(".", "-")
        assert f'id="{field_id}"' in form.text and f'for="{field_id}"' in form.text, name  # labelled
    made = page_post(api, "/courses/l03/setup/assignments", BERLIN_FORM)
    assert made.status_code == 303, made.text
    aid = int(made.headers["location"].rsplit("/", 1)[1])
    row = api.client.get(f"/v1/assignments/{aid}", headers=api.as_("prof")).json()
    assert (row["open_at"], row["due_at"], row["hard_close_at"]) == (
        "2026-12-01T09:00:00Z", "2026-12-08T09:00:00Z", "2026-12-10T17:30:00Z")  # CET is UTC+1 in December
    assert (row["title"], row["part"], row["late_penalty_per_day"], row["late_penalty_cap"], row["max_attempts"],
            row["max_per_hour"], row["counted_attempt"], row["visibility"], row["item_visibility"], row["created_by"]) \
        == ("Week 3", "checkpoints", 0.1, 0.3, 3, 2, "best", "after_due", {"C3": "on_release"}, "prof")
    assert changes()[-1] == ("assignment_created", "prof", f"created assignment {aid} 'Week 3'")


# Each bad value: the field the error names, and the same value sent to the API (None: a page-only rule).
BAD_FIELDS = [
    ({"title": ""}, "title", {"title": ""}),
    ({"due_at": "2026-11-30T10:00"}, "due_at", {"due_at": "2026-11-30T09:00:00Z"}),
    ({"hard_close_at": "2026-12-07T10:00"}, "hard_close_at", {"hard_close_at": "2026-12-07T09:00:00Z"}),
    ({"late_penalty_per_day": "1.5"}, "late_penalty_per_day", {"late_penalty_per_day": 1.5}),
    ({"late_penalty_per_day": "lots"}, "late_penalty_per_day", {"late_penalty_per_day": "lots"}),
    ({"late_penalty_cap": "-0.1"}, "late_penalty_cap", {"late_penalty_cap": -0.1}),
    ({"max_attempts": "0"}, "max_attempts", {"max_attempts": 0}),
    ({"max_attempts": "2.5"}, "max_attempts", {"max_attempts": "2.5"}),
    ({"max_per_hour": "1001"}, "max_per_hour", {"max_per_hour": 1001}),
    ({"part": "everything"}, "part", {"part": "everything"}),
    ({"counted_attempt": "first"}, "counted_attempt", {"counted_attempt": "first"}),
    ({"visibility": "never"}, "visibility", {"visibility": "never"}),
    ({"item_visibility.A1": "on_release"}, "item_visibility.A1", {"item_visibility": {"A1": "on_release"}}),
    ({"item_visibility.C2": "soon"}, "item_visibility.C2", {"item_visibility": {"C2": "soon"}}),
    ({"open_at": "next tuesday"}, "open_at", None),
    ({"open_at": ""}, "open_at", None),
    ({"open_at": "2026-03-29T02:30"}, "open_at", None),  # Berlin's clocks skip from 02:00 to 03:00 that night
]


@pytest.mark.parametrize("bad, field, api_body", BAD_FIELDS)
def test_each_bad_field_comes_back_beside_its_field_with_the_apis_message_nothing_stored(api, bad, field, api_body):
    set_zone(api)
    before = changes()
    response = page_post(api, "/courses/l03/setup/assignments", {**BERLIN_FORM, **bad})
    assert response.status_code == 422, response.text
    shown = error_beside(response.text, field)
    if api_body is not None:
        body = {"title": "Week 3", "part": "checkpoints", "open_at": "2026-12-01T09:00:00Z",
                "due_at": "2026-12-08T09:00:00Z", "hard_close_at": "2026-12-10T17:30:00Z", **api_body}
        refused = api.client.post("/v1/courses/l03/assignments", json=body, headers=api.as_("prof"))
        assert refused.status_code == 422
        # the API's message, naming fields by the form's labels ("due_at must be after open_at" reads
        # "“Due” must be after “Opens”")
        rules = [e["rule"] for e in in_form_words(refused.json()["errors"]) if e["field"] == field]
        assert rules and all(rule in shown for rule in rules), (shown, rules)
        assert "_at" not in shown
    else:
        assert "Europe/Berlin" in shown
    assert f'href="#f-{field.replace(".", "-")}"' in response.text  # the summary at the top links the field
    typed = {**BERLIN_FORM, **bad}
    assert f'value="{typed["title"]}"' in response.text and f'value="{typed["due_at"]}"' in response.text  # kept
    assert count(Assignment) == 0 and changes() == before


def test_every_error_of_a_form_is_shown_at_once(api):
    response = page_post(api, "/courses/l03/setup/assignments",
                         {**BERLIN_FORM, "title": "", "max_attempts": "0", "open_at": "soon",
                          "item_visibility.A1": "on_release"})
    assert response.status_code == 422
    for field in ("title", "max_attempts", "open_at", "item_visibility.A1"):
        error_beside(response.text, field)
    assert "Not saved: 4 problem(s)." in response.text


def test_an_edit_is_stored_whole_and_recorded_with_before_and_after(api):
    set_zone(api)
    aid = int(page_post(api, "/courses/l03/setup/assignments", BERLIN_FORM).headers["location"].rsplit("/", 1)[1])
    form = api.client.get(f"/assignments/{aid}/edit", headers=api.as_("prof")).text
    assert 'value="2026-12-08T10:00"' in form and 'value="0.3"' in form  # shown in the course's zone
    assert re.search(r'<option value="on_release" selected>on release</option>', form)  # C3's own setting
    edited = page_post(api, f"/assignments/{aid}/edit", {**BERLIN_FORM, "due_at": "2026-12-09T10:00",
                                                         "late_penalty_per_day": "0.2", "item_visibility.C3": ""})
    assert edited.status_code == 303 and edited.headers["location"] == f"/assignments/{aid}"
    row = api.client.get(f"/v1/assignments/{aid}", headers=api.as_("prof")).json()
    assert (row["due_at"], row["late_penalty_per_day"], row["item_visibility"]) == ("2026-12-09T09:00:00Z", 0.2, {})
    kind, who, summary = changes()[-1]
    assert (kind, who) == ("assignment_edited", "prof")
    assert summary == (f"edited assignment {aid} 'Week 3': due 2026-12-08 10:00 CET → 2026-12-09 10:00 CET; "
                       "late penalty per day 0.1 → 0.2; items shown C3 on_release → none")
    with new_session() as session:
        detail = session.scalars(select(CourseChange.detail).order_by(CourseChange.id.desc())).first()
    assert detail["due_at"] == ["2026-12-08T09:00:00+00:00", "2026-12-09T09:00:00+00:00"]
    # A refused edit stores nothing, not even the valid fields beside the bad one.
    refused = page_post(api, f"/assignments/{aid}/edit", {**BERLIN_FORM, "title": "Renamed", "max_attempts": "0"})
    assert refused.status_code == 422 and 'value="Renamed"' in refused.text
    assert api.client.get(f"/v1/assignments/{aid}", headers=api.as_("prof")).json()["title"] == "Week 3"
    assert len(changes()) == 3  # zone, create, edit


def test_once_students_submitted_the_part_is_fixed_and_other_settings_still_change(api):
    aid = create(api, title="Checkpoints", open_at=at(-1), due_at=at(1), hard_close_at=at(2)).json()["id"]
    assert submit(api, aid).status_code == 202
    form = api.client.get(f"/assignments/{aid}/edit", headers=api.as_("prof")).text
    assert "1 submission(s)" in form and 'id="f-part" disabled' in form
    values = {"title": "Checkpoints", "lesson": "L03", "part": "sheet", "open_at": at(-1)[:16],
              "due_at": at(1)[:16], "hard_close_at": at(2)[:16], "late_penalty_per_day": "0",
              "counted_attempt": "latest", "visibility": "immediate"}
    refused = page_post(api, f"/assignments/{aid}/edit", values)
    assert refused.status_code == 409
    assert "fixed once students have submitted: 1 submission answer the items of part 'checkpoints'" in \
        error_beside(refused.text, "part")
    assert api.client.get(f"/v1/assignments/{aid}", headers=api.as_("prof")).json()["part"] == "checkpoints"
    allowed = page_post(api, f"/assignments/{aid}/edit", {**values, "part": "checkpoints", "max_attempts": "5"})
    assert allowed.status_code == 303
    assert api.client.get(f"/v1/assignments/{aid}", headers=api.as_("prof")).json()["max_attempts"] == 5


# --- the roster: tokens and links shown once ----------------------------------------------------------------------

def upload(api, text: str, links: bool = False, who="prof"):
    return page_post(api, "/courses/l03/setup/roster", {"links": "1"} if links else {}, who=who,
                     files={"csv": ("roster.csv", text.encode("utf-8-sig"), "text/csv")})


def test_a_roster_upload_shows_the_new_tokens_and_links_once_and_as_a_csv(api):
    shown = upload(api, ROSTER + "alice,Alice Liddell,alice@example.edu\n", links=True)
    assert shown.status_code == 200, shown.text
    assert shown.headers["cache-control"] == "private, no-store"
    text = shown.text
    tokens = dict(re.findall(r'<tr id="issued-(s100\d)">.*?<code class="secret">([^<]+)</code>', text, re.S))
    links = re.findall(r'<code class="secret">(http://testserver/sign-in/link/[A-Za-z0-9_-]{43})</code>', text)
    assert set(tokens) == {"s1001", "s1002"} and len(links) == 3  # alice was there: a link, no new token
    assert "keeps their token" in re.search(r'<tr id="issued-alice">(.*?)</tr>', text, re.S).group(1)
    csv = unquote(re.search(r'href="data:text/csv;charset=utf-8,([^"]+)"', text).group(1))
    assert csv.splitlines()[0] == "student_id,name,email,token,sign_in_link"
    assert all(t in csv for t in tokens.values()) and all(link in csv for link in links)
    # Each token works for its student...
    me = api.client.get("/v1/courses/l03", headers={"Authorization": f"Bearer {tokens['s1001']}"})
    assert me.status_code == 200
    # ...and is never shown again: not on the set-up page, not on a re-import, not in the changes.
    setup = api.client.get("/courses/l03/setup", headers=api.as_("prof")).text
    assert not any(t in setup for t in tokens.values()) and not any(link in setup for link in links)
    again = upload(api, ROSTER)
    assert again.status_code == 200 and 'id="none-issued"' in again.text and "data:text/csv" not in again.text
    assert not any(t in again.text for t in tokens.values())
    with new_session() as session:
        details = repr(list(session.scalars(select(CourseChange.detail))))
    assert not any(t in details for t in tokens.values())
    assert [c[2] for c in changes()] == [
        "roster imported: 2 new (s1001, s1002), 1 updated (alice); new sign-in links for all 3 (earlier links revoked)",
        "roster imported: 0 new, 2 updated (s1001, s1002)"]


def test_a_bad_roster_names_each_line_and_stores_nobody(api):
    response = upload(api, "student_id,name,email\ns1001,Ada,ada@example.edu\nbad id!,Bob,not-an-email\n")
    assert response.status_code == 422
    errors = re.search(r'id="roster-errors">(.*?)</div>', response.text, re.S).group(1)
    assert "csv.line 3.student_id" in errors and "csv.line 3.email" in errors and "an email address" in errors
    assert "Nothing was changed." in errors
    with new_session() as session:
        assert session.scalar(select(User).where(User.name == "s1001")) is None
    assert changes() == []
    empty = page_post(api, "/courses/l03/setup/roster", {}, files={"csv": ("r.csv", b"", "text/csv")})
    assert empty.status_code == 422 and "choose a CSV file" in empty.text
    latin_1 = "student_id,name,email\nx,Jos\xe9,j@x.org\n".encode("latin-1")
    latin = page_post(api, "/courses/l03/setup/roster", {}, files={"csv": ("r.csv", latin_1, "text/csv")})
    assert latin.status_code == 422 and "UTF-8 text" in latin.text


def test_a_new_sign_in_link_is_shown_once_and_revokes_the_earlier(api):
    first = page_post(api, "/courses/l03/setup/students/alice/sign-in-link")
    assert first.status_code == 200
    old = re.search(r"http://testserver(/sign-in/link/[A-Za-z0-9_-]{43})", first.text).group(1)
    second = page_post(api, "/courses/l03/setup/students/alice/sign-in-link")
    new = re.search(r"http://testserver(/sign-in/link/[A-Za-z0-9_-]{43})", second.text).group(1)
    assert new != old and "Their earlier link no longer works." in second.text
    api.client.cookies.clear()
    assert "revoked at" in api.client.post(old, follow_redirects=False).text
    assert [c[:2] for c in changes()] == [("sign_in_link_issued", "prof")] * 2
    assert changes()[0][2] == "new sign-in link for alice (the earlier one revoked)"
    staff = page_post(api, "/courses/l03/setup/students/tess/sign-in-link")
    assert staff.status_code == 422 and "sign-in links are for students" in staff.text


# --- the assignment page: release, extensions ---------------------------------------------------------------------

def test_release_and_extensions_from_the_assignment_page_are_what_the_api_shows(api):
    set_zone(api)
    aid = create(api, item_visibility={"C3": "on_release"}).json()["id"]
    page = api.client.get(f"/assignments/{aid}", headers=api.as_("prof")).text
    assert 'id="release"' in page and "Shows C3 to every student at once" in page
    released = page_post(api, f"/assignments/{aid}/release")
    assert released.status_code == 303
    first = api.client.get(f"/v1/assignments/{aid}", headers=api.as_("prof")).json()["released_at"]
    assert first is not None
    page_post(api, f"/assignments/{aid}/release")  # again: the first release time stays, nothing recorded
    assert api.client.get(f"/v1/assignments/{aid}", headers=api.as_("prof")).json()["released_at"] == first
    assert 'id="release"' not in api.client.get(f"/assignments/{aid}", headers=api.as_("prof")).text
    granted = page_post(api, f"/assignments/{aid}/extensions",
                        {"student": "bob", "due_at": "2027-01-05T12:00", "hard_close_at": "2027-01-06T12:00"})
    assert granted.status_code == 303 and granted.headers["location"] == f"/assignments/{aid}#extensions"
    page = api.client.get(f"/assignments/{aid}", headers=api.as_("prof")).text
    row = re.search(r'<tr id="extension-bob">(.*?)</tr>', page, re.S).group(1)
    assert "2027-01-05 12:00 CET" in row and "by prof" in row
    with new_session() as session:
        ext = session.scalar(select(Extension))
        assert (ext.due_at.isoformat(), ext.hard_close_at.isoformat()) == ("2027-01-05T11:00:00", "2027-01-06T11:00:00")
    revoked = page_post(api, f"/assignments/{aid}/extensions/revoke", {"student": "bob"})
    assert revoked.status_code == 303 and count(Extension) == 0
    kinds = [c[0] for c in changes()]
    assert kinds[-3:] == ["released", "extension_granted", "extension_revoked"] and kinds.count("released") == 1
    page = api.client.get(f"/assignments/{aid}", headers=api.as_("prof")).text
    history = re.search(r'id="assignment-changes"(.*?)</section>', page, re.S).group(1)
    assert "extension of bob on assignment" in history and "revoked (was due 2027-01-05 12:00 CET" in history


@pytest.mark.parametrize("data, field, rule", [
    ({"student": "bob", "due_at": "2027-01-05T12:00", "hard_close_at": "2027-01-04T12:00"}, "hard_close_at",
     "“Hard close” must not be before “Due”"),
    ({"student": "nobody", "due_at": "2027-01-05T12:00", "hard_close_at": "2027-01-06T12:00"}, "student",
     "no student &#39;nobody&#39; in this course"),
    ({"student": "", "due_at": "2027-01-05T12:00", "hard_close_at": "2027-01-06T12:00"}, "student",
     "at least 1 character"),
    ({"student": "bob", "due_at": "", "hard_close_at": "2027-01-06T12:00"}, "due_at", "required: a date and time"),
])
def test_a_refused_extension_names_its_field_and_keeps_the_values(api, data, field, rule):
    aid = create(api).json()["id"]
    response = page_post(api, f"/assignments/{aid}/extensions", data)
    assert response.status_code == 422
    errors = re.search(r'id="extension-errors">(.*?)</div>', response.text, re.S).group(1)
    label = {"student": "Student", "due_at": "Due", "hard_close_at": "Hard close"}[field]
    assert f"<li>{label}: " in errors and rule in errors and "<code>" not in errors  # the field by its label
    assert f'value="{data["hard_close_at"]}"' in response.text
    assert count(Extension) == 0 and [c[0] for c in changes()] == ["assignment_created"]


def test_revoking_an_extension_nobody_has_is_refused(api):
    aid = create(api).json()["id"]
    response = page_post(api, f"/assignments/{aid}/extensions/revoke", {"student": "bob"})
    assert response.status_code == 422 and "&#39;bob&#39; has no extension of assignment" in response.text


def test_the_api_records_its_changes_too(api):
    aid = create(api).json()["id"]
    api.client.post(f"/v1/assignments/{aid}/extensions", headers=api.as_("prof"),
                    json={"student": "bob", "due_at": at(2), "hard_close_at": at(3)}).raise_for_status()
    api.client.post(f"/v1/assignments/{aid}/release", headers=api.as_("prof")).raise_for_status()
    api.client.post("/v1/courses/l03/roster", headers=api.as_("prof"), json={"csv": ROSTER}).raise_for_status()
    api.client.post("/v1/courses/l03/students/alice/sign-in-link", headers=api.as_("prof")).raise_for_status()
    set_zone(api)
    assert [(k, who) for k, who, _ in changes()] == [
        ("assignment_created", "prof"), ("extension_granted", "prof"), ("released", "prof"),
        ("roster_imported", "prof"), ("sign_in_link_issued", "prof"), ("course_settings", "prof")]
    # A refused API call records nothing.
    bad = api.client.post(f"/v1/assignments/{aid}/extensions", headers=api.as_("prof"),
                          json={"student": "nobody", "due_at": at(2), "hard_close_at": at(3)})
    assert bad.status_code == 422 and len(changes()) == 6
