"""`grader course ...`: a course's settings over the HTTP API (its time zone)."""

from __future__ import annotations

import click

from grader.cli.rubric import TOKEN, URL, _call, _client


@click.group()
def course() -> None:
    """A course's settings (instructors change them; everyone in the course may read them)."""


@course.command()
@click.argument("course_name", metavar="COURSE")
@click.argument("zone", required=False)
@URL
@TOKEN
def timezone(course_name: str, zone: str | None, url: str, token: str) -> None:
    """Show COURSE's time zone, or set it to ZONE (an IANA name such as Europe/Berlin). Times stay stored in UTC;
    the pages and refusal messages show them in this zone."""
    client = _client(url, token)
    row = _call(client.update_course, course_name, {"timezone": zone}) if zone else _call(client.course, course_name)
    click.echo(f"course {row['name']}: times shown in {row['timezone']}")
