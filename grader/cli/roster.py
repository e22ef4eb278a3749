"""`grader roster import` and `grader roster link`: a course's students from a CSV file, and their sign-in links;
new tokens and links are written where only the caller reads them."""

from __future__ import annotations

import os
from pathlib import Path

import click

from grader.cli.assignment import _in_zone
from grader.cli.rubric import TOKEN, URL, _call, _client


@click.group()
def roster() -> None:
    """A course's roster of students (instructors)."""


def _private_file(path: Path):
    """A new file only its owner may read or write (0600 from the start, never widened): refuses an existing one."""
    try:
        fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    except FileExistsError:
        raise click.BadParameter(f"{path} exists; give a new file (tokens are never written over another)",
                                 param_hint="--tokens-out") from None
    return os.fdopen(fd, "w")


def _rows(entries: list[dict], links: bool) -> str:
    """The file's CSV: each new student's token, and with --links every student's sign-in link."""
    if not links:
        return "student_id,token\n" + "".join(f"{e['student']},{e['token']}\n" for e in entries if e["created"])
    return "student_id,token,sign_in_link\n" + "".join(
        f"{e['student']},{e['token'] or ''},{e['sign_in_link']}\n" for e in entries)


@roster.command("import")
@click.argument("course")
@click.argument("csv_file", type=click.Path(exists=True, dir_okay=False, path_type=Path))
@click.option("--tokens-out", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="Write the new students' tokens (and with --links every sign-in link) to this new file (mode "
                   "0600) instead of printing them")
@click.option("--links", is_flag=True, help="Also issue every student of the file a new sign-in link (single use, "
                                            "expiring; their earlier link stops working)")
@URL
@TOKEN
def import_roster(course: str, csv_file: Path, tokens_out: Path | None, links: bool, url: str, token: str) -> None:
    """Import CSV_FILE (student_id,name,email) into COURSE: new students are created and get a token, shown this
    once; students already there keep theirs and get the file's name and email."""
    out = _private_file(tokens_out) if tokens_out else None  # before the import: its tokens must have a place
    client = _client(url, token)
    try:
        entries = _call(client.import_roster, course, csv_file.read_text(), links)
    except BaseException:
        if out is not None:
            out.close()
            tokens_out.unlink()
        raise
    new = [e for e in entries if e["created"]]
    if out is not None:
        with out:
            out.write(_rows(entries, links))
    for e in entries:
        shown = ""
        if out is None:
            shown = (f"  token {e['token']}" if e["created"] else "") + (f"  link {e['sign_in_link']}" if links else "")
        state = "created" if e["created"] else "updated"
        click.echo(f"{e['student']:<12} {state:<8} {e['name']} <{e['email']}>{shown}")
    what = "tokens and sign-in links" if links else "tokens"
    where = f", their {what} in {tokens_out} (mode 0600)" if out is not None else ""
    expiry = (f"; each link works once, until {_in_zone(client, course)(entries[0]['sign_in_link_expires_at'])}"
              if links else "")
    click.echo(f"{len(new)} new students, {len(entries) - len(new)} updated{where}{expiry}")


@roster.command("link")
@click.argument("course")
@click.argument("student")
@URL
@TOKEN
def reissue_link(course: str, student: str, url: str, token: str) -> None:
    """Issue STUDENT of COURSE a new sign-in link (printed once); their earlier link stops working."""
    client = _client(url, token)
    issued = _call(client.sign_in_link, course, student)
    click.echo(f"{issued['student']}: {issued['sign_in_link']}")
    click.echo(f"works once, until {_in_zone(client, course)(issued['expires_at'])}; the earlier link no longer works")
