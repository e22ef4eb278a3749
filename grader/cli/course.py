"""`grader course ...`: a course's settings over the HTTP API (its time zone, free submissions)."""

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


@course.command(name="free-submissions")
@click.argument("course_name", metavar="COURSE")
@click.argument("allowed", required=False, type=click.Choice(["on", "off"]))
@URL
@TOKEN
def free_submissions(course_name: str, allowed: str | None, url: str, token: str) -> None:
    """Show whether COURSE's students may submit outside an assignment, or turn it on or off. Where on, what an
    assignment withholds is withheld in those submissions too; staff may always submit outside one."""
    client = _client(url, token)
    row = (_call(client.update_course, course_name, {"free_submissions": allowed == "on"}) if allowed
           else _call(client.course, course_name))
    click.echo(f"course {row['name']}: " + ("students may also submit outside assignments" if row["free_submissions"]
                                            else "students submit only to an assignment"))
