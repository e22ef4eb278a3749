"""`grader assignment ...`: a course's assignments over the HTTP API (like `grader rubric`)."""

from __future__ import annotations

import click

from grader.cli.rubric import TOKEN, URL, _call, _client


@click.group()
def assignment() -> None:
    """Assignments of a course (instructors create; everyone in the course may list)."""


@assignment.command()
@click.argument("course")
@click.option("--title", required=True)
@click.option("--lesson", default="L03", show_default=True)
@click.option("--items", type=click.Choice(["checkpoints", "exercises", "sheet"]), default="sheet", show_default=True)
@click.option("--open", "open_at", required=True, help="ISO 8601 with an offset, e.g. 2026-12-01T09:00:00+00:00")
@click.option("--due", "due_at", required=True)
@click.option("--close", "hard_close_at", required=True, help="The hard close: nothing is accepted after it")
@click.option("--penalty-per-day", type=float, default=0.0, show_default=True, help="Fraction per day late")
@click.option("--penalty-cap", type=float, default=None, help="The most the late penalty may take (fraction)")
@click.option("--max-attempts", type=int, default=None)
@click.option("--counted", "counted_attempt", type=click.Choice(["latest", "best"]), default="latest",
              show_default=True)
@click.option("--visibility", type=click.Choice(["immediate", "after_due", "on_release"]), default="immediate",
              show_default=True)
@URL
@TOKEN
def create(course: str, url: str, token: str, **fields) -> None:
    """Create an assignment in COURSE."""
    body = {"late_penalty_per_day": fields.pop("penalty_per_day"), "late_penalty_cap": fields.pop("penalty_cap"),
            **fields}
    row = _call(_client(url, token).create_assignment, course, body)
    click.echo(f"assignment #{row['id']} {row['title']!r} ({row['items']}: {', '.join(row['item_ids'])}) "
               f"open {row['open_at']}, due {row['due_at']}, closes {row['hard_close_at']}")


@assignment.command("list")
@click.argument("course")
@URL
@TOKEN
def list_assignments(course: str, url: str, token: str) -> None:
    """Every assignment of COURSE, by due date."""
    for a in _call(_client(url, token).assignments, course):
        attempts = a["max_attempts"] or "unlimited"
        click.echo(f"#{a['id']:<5} {a['title']:<28} {a['items']:<11} due {a['due_at']}  closes {a['hard_close_at']}  "
                   f"attempts {attempts}, counts {a['counted_attempt']}, late {a['late_penalty_per_day']:g}/day")
