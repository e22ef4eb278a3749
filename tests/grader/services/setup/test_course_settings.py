"""A course's time zone: read and set over the API and the CLI, refused when unknown, shown in refusals and pages."""

from __future__ import annotations

import pytest

from tests.grader.services.setup.test_assignments import at, create, refused, submit
from tests.grader.services.setup.test_assignments import lesson_cases_stored  # noqa: F401 - autouse: the lesson measured


def patch(api, body, who="prof", course="l03"):
    return api.client.patch(f"/v1/courses/{course}", json=body, headers=api.as_(who))


def test_an_instructor_sets_the_zone_everyone_in_the_course_reads_it(api):
    assert api.client.get("/v1/courses/l03", headers=api.as_("alice")).json()["timezone"] == "UTC"
    response = patch(api, {"timezone": "Europe/Berlin"})
    assert response.status_code == 200, response.text
    for who in ("alice", "tess", "prof"):
        assert api.client.get("/v1/courses/l03", headers=api.as_(who)).json()["timezone"] == "Europe/Berlin"


@pytest.mark.parametrize("who, body, status, field", [
    ("prof", {"timezone": "Mars/Olympus"}, 422, "timezone"),
    ("prof", {"timezone": "../../etc/passwd"}, 422, "timezone"),
    ("prof", {"timezone": "localtime"}, 422, "timezone"),
    ("prof", {"timezone": ""}, 422, "timezone"),
    ("prof", {"zone": "UTC"}, 422, "zone"),
    ("alice", {"timezone": "Europe/Berlin"}, 403, None),
    ("tess", {"timezone": "Europe/Berlin"}, 403, None),
    ("eve", {"timezone": "Europe/Berlin"}, 404, None),
])
def test_bad_zones_and_callers_are_refused_nothing_changed(api, who, body, status, field):
    response = patch(api, body, who=who)
    assert response.status_code == status, response.text
    if field:
        assert field in {e["field"] for e in response.json()["errors"]}, response.json()
    assert api.client.get("/v1/courses/l03", headers=api.as_("prof")).json()["timezone"] == "UTC"


@pytest.mark.clock("2026-11-25T10:00:00Z")  # a day after the hard close below, whatever the calendar says
def test_refusals_and_pages_show_times_in_the_course_zone(api):
    assert patch(api, {"timezone": "Asia/Kolkata"}).status_code == 200
    closed = create(api, open_at=at(-3), due_at=at(-2), hard_close_at="2026-11-24T10:00:00Z").json()
    refused(submit(api, closed["id"]), "closed at 2026-11-24T15:30:00+05:30 (Asia/Kolkata)")
    ok = create(api).json()
    sid = submit(api, ok["id"]).json()["id"]
    assert "IST" in api.client.get(f"/submissions/{sid}", headers=api.as_("alice")).text
    assert "submitted (Asia/Kolkata)" in api.client.get("/submissions", headers=api.as_("alice")).text


def test_the_cli_reads_and_sets_the_zone(api, monkeypatch):
    from click.testing import CliRunner

    from grader.cli import course, main
    from tests.grader.cli.test_assignment_cli import client_on

    monkeypatch.setattr(course, "_client", client_on)
    done = CliRunner().invoke(main, ["course", "timezone", "l03", "America/New_York", "--token", api.tokens["prof"]])
    assert done.exit_code == 0 and "times shown in America/New_York" in done.output, done.output
    shown = CliRunner().invoke(main, ["course", "timezone", "l03", "--token", api.tokens["alice"]])
    assert "America/New_York" in shown.output
    bad = CliRunner().invoke(main, ["course", "timezone", "l03", "Nowhere/Land", "--token", api.tokens["prof"]])
    assert bad.exit_code != 0 and "timezone: 'Nowhere/Land' is not an IANA time zone" in bad.output
