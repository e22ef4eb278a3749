"""`grader assignment ...`: a course's assignments over the HTTP API (like `grader rubric`)."""

from __future__ import annotations

from pathlib import Path

import click

from grader.cli.rubric import TOKEN, URL, _call, _client


VISIBILITIES = ["immediate", "after_due", "on_release"]


def _item_visibility(ctx, param, values: tuple[str, ...]) -> dict[str, str]:
    out = {}
    for value in values:
        item, sep, when = value.partition("=")
        if not sep or not item or when not in VISIBILITIES:
            raise click.BadParameter(f"{value!r}: ITEM=WHEN with WHEN one of {', '.join(VISIBILITIES)}")
        out[item] = when
    return out


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
@click.option("--max-per-hour", type=int, default=None, help="Submissions one student may make in any 60 minutes")
@click.option("--visibility", type=click.Choice(VISIBILITIES), default="immediate", show_default=True,
              help="When students see scores and feedback")
@click.option("--item-visibility", "item_visibility", multiple=True, callback=_item_visibility, metavar="ITEM=WHEN",
              help="One item shown otherwise than --visibility, e.g. C3=on_release (repeatable)")
@URL
@TOKEN
def create(course: str, url: str, token: str, **fields) -> None:
    """Create an assignment in COURSE."""
    body = {"late_penalty_per_day": fields.pop("penalty_per_day"), "late_penalty_cap": fields.pop("penalty_cap"),
            **fields}
    row = _call(_client(url, token).create_assignment, course, body)
    click.echo(f"assignment #{row['id']} {row['title']!r} ({row['items']}: {', '.join(row['item_ids'])}) "
               f"open {row['open_at']}, due {row['due_at']}, closes {row['hard_close_at']}")
    if row["item_visibility"]:
        click.echo("shown " + ", ".join(f"{k} {v}" for k, v in row["item_visibility"].items()) +
                   f"; the other items {row['visibility']}")


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


@assignment.command()
@click.argument("assignment_id", type=int)
@URL
@TOKEN
def release(assignment_id: int, url: str, token: str) -> None:
    """Show ASSIGNMENT_ID's withheld scores and feedback (items on_release) to its students, without regrading."""
    row = _call(_client(url, token).release, assignment_id)
    click.echo(f"assignment #{row['id']} {row['title']!r} released at {row['released_at']}")


@assignment.command()
@click.argument("assignment_id", type=int)
@click.argument("student")
@click.option("--due", "due_at", required=True, help="The student's own due date (ISO 8601 with an offset)")
@click.option("--close", "hard_close_at", required=True, help="The student's own hard close")
@URL
@TOKEN
def extend(assignment_id: int, student: str, url: str, token: str, **dates) -> None:
    """Give STUDENT their own due date and hard close for ASSIGNMENT_ID (recorded with who granted it)."""
    row = _call(_client(url, token).extend, assignment_id, {"student": student, **dates})
    click.echo(f"{row['student']}: due {row['due_at']}, closes {row['hard_close_at']} "
               f"(granted by {row['granted_by']} at {row['granted_at']})")


@assignment.command()
@click.argument("assignment_id", type=int)
@click.option("--csv", "csv_out", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="Write the CSV export here (- for standard output) instead of printing a table")
@URL
@TOKEN
def grades(assignment_id: int, url: str, token: str, csv_out: Path | None) -> None:
    """The counted grade of each student of ASSIGNMENT_ID: counted, raw, late penalty, attempt, when."""
    client = _client(url, token)
    if csv_out is not None:
        text = _call(client.counted_grades_csv, assignment_id)
        if str(csv_out) == "-":
            click.echo(text, nl=False)
        else:
            csv_out.write_text(text)
            click.echo(f"{len(text.splitlines()) - 1} students written to {csv_out}")
        return
    rows = _call(client.counted_grades, assignment_id)
    click.echo(f"{'student':<12} {'counted':>8} {'raw':>6} {'penalty':>8} {'attempt':>8}  submitted (UTC)")
    for r in rows:
        click.echo(f"{r['student']:<12} {r['counted_score']:>8g} {r['raw_score']:>6g} {r['penalty']:>8.0%} "
                   f"{r['attempt']:>8}  {r['submitted_at']}")
    if not rows:
        click.echo("no graded submission yet")
