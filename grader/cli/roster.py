"""`grader roster import`: a course's students from a CSV file, their new tokens written where only the caller reads
them."""

from __future__ import annotations

import os
from pathlib import Path

import click

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


@roster.command("import")
@click.argument("course")
@click.argument("csv_file", type=click.Path(exists=True, dir_okay=False, path_type=Path))
@click.option("--tokens-out", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="Write the new students' tokens to this new file (mode 0600) instead of printing them")
@URL
@TOKEN
def import_roster(course: str, csv_file: Path, tokens_out: Path | None, url: str, token: str) -> None:
    """Import CSV_FILE (student_id,name,email) into COURSE: new students are created and get a token, shown this
    once; students already there keep theirs and get the file's name and email."""
    out = _private_file(tokens_out) if tokens_out else None  # before the import: its tokens must have a place
    try:
        entries = _call(_client(url, token).import_roster, course, csv_file.read_text())
    except BaseException:
        if out is not None:
            out.close()
            tokens_out.unlink()
        raise
    new = [e for e in entries if e["created"]]
    if out is not None:
        with out:
            out.write("student_id,token\n" + "".join(f"{e['student']},{e['token']}\n" for e in new))
    for e in entries:
        shown = "" if out is not None or not e["created"] else f"  token {e['token']}"
        state = "created" if e["created"] else "updated"
        click.echo(f"{e['student']:<12} {state:<8} {e['name']} <{e['email']}>{shown}")
    where = f", their tokens in {tokens_out} (mode 0600)" if out is not None else ""
    click.echo(f"{len(new)} new students, {len(entries) - len(new)} updated{where}")
