"""A student's course page (issue 22, item 2): per assignment the dates that apply to them in the course's zone,
attempts used and left, the hourly limit, what a submission now would meet (late by how much, the penalty, or the
rule refusing it), and the counted score so far linked to each attempt's report; withheld scores stay withheld."""

from __future__ import annotations

import html
import re
from datetime import datetime

from grader.core.timezones import local
from tests.grader.services.setup.test_assignments import at, create, submit
from tests.grader.services.setup.test_assignments import lesson_cases_stored  # noqa: F401 - autouse: the lesson measured

ZONE = "Asia/Shanghai"


def _page(api, who="alice", course="l03"):
    return api.client.get(f"/courses/{course}", headers=api.as_(who), follow_redirects=False)


def _section(text: str, aid: int) -> str:
    start = text.index(f'id="assignment-{aid}"')
    return html.unescape(text[start:text.index("</section>", start)])


def _text(section: str) -> str:
    """What a reader sees of a section: no tags, single spaces."""
    return " ".join(re.sub(r"<[^>]+>", " ", section).split()).replace(" ,", ",").replace(" :", ":").replace(" .", ".")


def _shown(iso: str) -> str:
    """A time as the page shows it in the course's zone."""
    return local(datetime.fromisoformat(iso.replace("Z", "+00:00")), ZONE)


def test_the_course_page_shows_each_assignment_as_it_applies_to_the_student_now(api):
    assert api.client.patch("/v1/courses/l03", json={"timezone": ZONE}, headers=api.as_("prof")).status_code == 200
    open_now = create(api, title="On time", max_attempts=3, max_per_hour=2, late_penalty_per_day=0.1).json()
    past_due = create(api, title="Past due", open_at=at(-3), due_at=at(hours=-26), hard_close_at=at(2),
                      late_penalty_per_day=0.25, late_penalty_cap=0.4).json()
    extended = create(api, title="Extended", due_at=at(hours=-2), hard_close_at=at(hours=-1)).json()
    closed = create(api, title="Closed", open_at=at(-3), due_at=at(-2), hard_close_at=at(-1)).json()
    upcoming = create(api, title="Upcoming", open_at=at(1), due_at=at(2), hard_close_at=at(3)).json()
    granted = api.client.post(f"/v1/assignments/{extended['id']}/extensions", headers=api.as_("prof"),
                              json={"student": "alice", "due_at": at(1), "hard_close_at": at(2)}).json()
    first = submit(api, open_now["id"]).json()
    assert first["status"] == "graded" and first["total"] == 8
    late = submit(api, past_due["id"]).json()
    assert late["late_seconds"] > 86400

    page = _page(api)
    assert page.status_code == 200, page.text
    assert f'href="/courses/l03"' in page.text  # the nav link
    on_time = _section(page.text, open_now["id"])
    assert "open</span>" in on_time and f"course's time zone, {ZONE}" in html.unescape(page.text)
    for key in ("open_at", "due_at", "hard_close_at"):
        assert _shown(open_now[key]) in on_time and "CST" in _shown(open_now[key])
    assert "1 used, 2 left of 3" in on_time and "2 submissions per hour (1 in the last hour)" in on_time
    assert "Accepted as attempt 2, on time, no late penalty" in _text(on_time)
    assert f'href="/assignments/{open_now["id"]}/sheet"' in on_time  # where the student answers it
    assert f'href="/assignments/{closed["id"]}/sheet"' not in _section(page.text, closed["id"])  # nothing to answer
    assert "Score that counts 8 / 8 from attempt 1" in _text(on_time)
    assert f'<a href="/submissions/{first["id"]}">attempt 1</a>' in on_time and "counts</span>" in on_time

    overdue = _text(_section(page.text, past_due["id"]))
    assert "open, past the due date" in overdue
    assert re.search(r"Accepted as attempt 2, 1 d 2 h (\d+ min )?late \(2 days charged\): a late penalty of 40% of "
                     "its score", overdue), overdue
    assert "25% per started day late, at most 40%" in overdue
    # The attempt made 26 h late: its raw 8, 40% off, counted 4.8, linked to its report.
    assert f'href="/submissions/{late["id"]}"' in _section(page.text, past_due["id"])
    assert "4.8 / 8 from attempt 1 (raw 8, late penalty −40%)" in overdue

    mine = _section(page.text, extended["id"])
    assert "Dates (your extension)" in mine and _shown(granted["due_at"]) in mine
    assert _shown(extended["due_at"]) not in mine and "Accepted as attempt 1, on time" in _text(mine)
    # Bob has no extension: the same assignment is closed for him.
    assert "Not accepted now:" in _section(_page(api, "bob").text, extended["id"])

    shut = _section(page.text, closed["id"])
    # The refusal names the assignment by its title and its times as the page writes dates (course zone, no ISO).
    assert "closed</span>" in shut and f"Not accepted now: “{closed['title']}” closed at" in _text(shut)
    assert "its hard close; it is now" in _text(shut) and not re.search(r"\d{4}-\d\d-\d\dT\d", _text(shut))
    soon = _section(page.text, upcoming["id"])
    assert "not open yet" in soon and "opens at" in soon and "No attempts yet." in soon
    assert "none yet: no graded attempt" in soon


def test_a_withheld_score_stays_withheld_on_the_course_page(api):
    hidden = create(api, title="Hidden", visibility="on_release", counted_attempt="best").json()
    made = submit(api, hidden["id"]).json()
    assert made["status"] == "graded"
    section = _section(_page(api).text, hidden["id"])
    assert "8 / 8" not in section and "not shown yet: scores and feedback are shown once" in section
    assert "counts</span>" not in section  # under "best", which attempt counts would tell the hidden score
    assert f'href="/submissions/{made["id"]}"' in section
    api.client.post(f"/v1/assignments/{hidden['id']}/release", headers=api.as_("prof"))
    assert "Score that counts 8 / 8 from attempt 1" in _text(_section(_page(api).text, hidden["id"]))


def test_staff_go_to_their_dashboard_and_nobody_sees_another_courses_page(api):
    create(api, title="Mine")
    staff = _page(api, "prof")
    assert staff.status_code == 303 and staff.headers["location"] == "/courses/l03/dashboard"
    assert _page(api, "tess").headers["location"] == "/courses/l03/dashboard"
    for who, course in (("eve", "l03"), ("alice", "other"), ("alice", "nowhere")):
        refused = _page(api, who, course)
        assert refused.status_code == 404 and "Mine" not in refused.text
    api.client.cookies.clear()
    anonymous = api.client.get("/courses/l03", follow_redirects=False)
    assert anonymous.status_code == 303 and anonymous.headers["location"].startswith("/sign-in?next=")


def test_a_student_with_no_assignment_sees_so(api):
    page = _page(api, "bob")
    assert page.status_code == 200 and "No assignments yet." in page.text
