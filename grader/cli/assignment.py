"""`grader assignment ...`: a course's assignments over the HTTP API (like `grader rubric`)."""

from __future__ import annotations

import json
from datetime import datetime
from pathlib import Path

import click

from grader.core.states import AssignmentParts, Visibility, values
from grader.core.timezones import local

from grader.cli.rubric import TOKEN, URL, _call, _client


VISIBILITIES = values(Visibility)


def _item_visibility(ctx, param, values: tuple[str, ...]) -> dict[str, str]:
    out = {}
    for value in values:
        item, sep, when = value.partition("=")
        if not sep or not item or when not in VISIBILITIES:
            raise click.BadParameter(f"{value!r}: ITEM=WHEN with WHEN one of {', '.join(VISIBILITIES)}")
        out[item] = when
    return out


def _in_zone(client, course: str):
    """ISO times from the API (UTC) -> as the course shows them ('2026-12-08 10:00 CET')."""
    zone = _call(client.course, course)["timezone"]
    return lambda iso: local(datetime.fromisoformat(iso.replace("Z", "+00:00")), zone)


@click.group()
def assignment() -> None:
    """Assignments of a course (instructors create; everyone in the course may list)."""


@assignment.command()
@click.argument("course")
@click.option("--title", required=True)
@click.option("--lesson", default="L03", show_default=True)
@click.option("--part", type=click.Choice(values(AssignmentParts)), default="sheet", show_default=True,
              help="The part of the sheet it holds: the concept checkpoints, the exercises (every other item) or all")
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
    client = _client(url, token)
    row = _call(client.create_assignment, course, body)
    t = _in_zone(client, course)
    click.echo(f"assignment #{row['id']} {row['title']!r} ({row['part']}: {', '.join(row['item_ids'])}) "
               f"open {t(row['open_at'])}, due {t(row['due_at'])}, closes {t(row['hard_close_at'])}")
    if row["item_visibility"]:
        click.echo("shown " + ", ".join(f"{k} {v}" for k, v in row["item_visibility"].items()) +
                   f"; the other items {row['visibility']}")


@assignment.command("list")
@click.argument("course")
@URL
@TOKEN
def list_assignments(course: str, url: str, token: str) -> None:
    """Every assignment of COURSE, by due date."""
    client = _client(url, token)
    t = _in_zone(client, course)
    for a in _call(client.assignments, course):
        attempts = a["max_attempts"] or "unlimited"
        per_hour = f" ({a['max_per_hour']}/hour)" if a["max_per_hour"] else ""
        click.echo(f"#{a['id']:<3} {a['title']:<20} {a['part']:<11} due {t(a['due_at'])}, closes "
                   f"{t(a['hard_close_at'])}; attempts {attempts}{per_hour}, counts {a['counted_attempt']}, "
                   f"late {a['late_penalty_per_day']:g}/day")


@assignment.command()
@click.argument("assignment_id", type=int)
@URL
@TOKEN
def release(assignment_id: int, url: str, token: str) -> None:
    """Show ASSIGNMENT_ID's withheld scores and feedback (items on_release) to its students, without regrading."""
    client = _client(url, token)
    row = _call(client.release, assignment_id)
    released = _in_zone(client, row["course"])(row["released_at"])
    click.echo(f"assignment #{row['id']} {row['title']!r} released at {released}")


@assignment.command()
@click.argument("assignment_id", type=int)
@click.argument("student")
@click.option("--due", "due_at", required=True, help="The student's own due date (ISO 8601 with an offset)")
@click.option("--close", "hard_close_at", required=True, help="The student's own hard close")
@URL
@TOKEN
def extend(assignment_id: int, student: str, url: str, token: str, **dates) -> None:
    """Give STUDENT their own due date and hard close for ASSIGNMENT_ID (recorded with who granted it)."""
    client = _client(url, token)
    row = _call(client.extend, assignment_id, {"student": student, **dates})
    t = _in_zone(client, _call(client.assignment, assignment_id)["course"])
    click.echo(f"{row['student']}: due {t(row['due_at'])}, closes {t(row['hard_close_at'])} "
               f"(granted by {row['granted_by']} at {t(row['granted_at'])})")


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
    t = _in_zone(client, _call(client.assignment, assignment_id)["course"])
    click.echo(f"{'student':<12} {'counted':>8} {'raw':>6} {'penalty':>8} {'attempt':>8}  submitted")
    for r in rows:
        click.echo(f"{r['student']:<12} {r['counted_score']:>8g} {r['raw_score']:>6g} {r['penalty']:>8.0%} "
                   f"{r['attempt']:>8}  {t(r['submitted_at'])}")
    if not rows:
        click.echo("no graded submission yet")


@assignment.group()
def variants() -> None:
    """An assignment's pool of per-student lab variants: generate (instructors, before it opens), list, copy flags."""


@variants.command("generate")
@click.argument("assignment_id", type=int)
@click.option("--seed", type=int, required=True, help="The draw's seed: the same seed draws the same pool")
@click.option("-k", "--k", "k", type=int, default=16, show_default=True,
              help="How many variants to keep: drawn and measured until K pass the lab check or the budget is spent")
@click.option("--budget", type=int, default=None, help="The most variants to draw (K to 4 x K; default 2 x K)")
@click.option("--minimum", type=int, default=None,
              help="Variants kept before students get one (1 to K; default: once the pool is ready)")
@URL
@TOKEN
def generate_variants(assignment_id: int, seed: int, k: int, budget: int | None, minimum: int | None, url: str,
                      token: str) -> None:
    """Keep K variants for ASSIGNMENT_ID and queue their lesson runs; `list` shows which are kept as checks land."""
    body = {"seed": seed, "k": k} | ({"budget": budget} if budget else {}) | ({"minimum": minimum} if minimum else {})
    pool = _call(_client(url, token).generate_variants, assignment_id, body)
    _echo_pool(pool)


@variants.command("top-up")
@click.argument("assignment_id", type=int)
@click.option("--more", type=int, default=None, help="Variants more to keep (at any time; students keep theirs)")
@URL
@TOKEN
def top_up_variants(assignment_id: int, more: int | None, url: str, token: str) -> None:
    """Draw ASSIGNMENT_ID's pool further from its seed (MORE variants more to keep, or the K - kept it lacks) and
    measure the new ones."""
    _echo_pool(_call(_client(url, token).top_up_variants, assignment_id, more))


@variants.command("list")
@click.argument("assignment_id", type=int)
@click.option("--json", "as_json", is_flag=True, help="Print the pool as JSON (a variant's entry is what "
                                                       "`grader grade --variant` takes)")
@URL
@TOKEN
def list_variants(assignment_id: int, as_json: bool, url: str, token: str) -> None:
    """The pool of ASSIGNMENT_ID: each variant's state (measuring, kept, dropped), reason and students (staff)."""
    pool = _call(_client(url, token).variants, assignment_id)
    if pool is None:
        click.echo(f"assignment #{assignment_id} has no variant pool: its students work on the lesson's shipped cases")
        return
    if as_json:
        click.echo(json.dumps(pool, indent=2))
    else:
        _echo_pool(pool)


@variants.command("flags")
@click.argument("assignment_id", type=int)
@URL
@TOKEN
def copy_flags(assignment_id: int, url: str, token: str) -> None:
    """Submissions of ASSIGNMENT_ID whose answers fit another variant rather than their own (staff)."""
    rows = _call(_client(url, token).copy_flags, assignment_id)
    for r in rows:
        click.echo(f"submission #{r['submission_id']} {r['student']} (variant {r['own_variant']}): "
                   f"fits {r['fits_variant']} on {', '.join(r['items'])}")
    if not rows:
        click.echo("no copy evidence")


def _echo_pool(pool: dict) -> None:
    click.echo(f"assignment #{pool['assignment_id']}: pool of {pool['k']} (seed {pool['seed']}, {pool['lesson']} "
               f"variant space v{pool['space_version']}, rubric v{pool['rubric_version']}): {pool['state']}, "
               f"{pool['kept']} kept, {pool['dropped']} dropped; {pool['outcome']}")
    for v in pool["variants"]:
        click.echo(f"  {v['id']:<10} {v['state']:<9} {v['students']:>3} students"
                   + (f"  {v['reason']}" if v["reason"] else ""))
