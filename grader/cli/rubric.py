"""`grader rubric ...`: an instructor's rubric versions and regrades, over the HTTP API (like `grader submit`)."""

from __future__ import annotations

import json
from pathlib import Path

import click
import yaml

URL = click.option("--url", envvar="GRADER_URL", default="http://127.0.0.1:8000", show_default=True)
TOKEN = click.option("--token", envvar="GRADER_TOKEN", required=True, help="An instructor's API token (or GRADER_TOKEN).")
LESSON = click.option("--lesson", default="L03", show_default=True)


def _client(url: str, token: str):
    from grader.client import Client  # lazy: httpx (~0.1 s) only for the HTTP commands, not `grader --help`

    return Client(url, token)


def _call(fn, *args):
    try:
        return fn(*args)
    except RuntimeError as exc:  # the API's error, with each field and rule
        raise click.ClickException(str(exc)) from exc


@click.group()
def rubric() -> None:
    """Rubric versions and regrades of a course (instructors; auditors may list and preview)."""


@rubric.command("list")
@URL
@TOKEN
@LESSON
def list_versions(url: str, token: str, lesson: str) -> None:
    """Every version of a lesson's rubric your course may use (shipped, or published in it), with who published it."""
    for v in _call(_client(url, token).rubric_versions, lesson):
        who = f"published by {v['published_by']}" if v["published_by"] else "shipped"
        click.echo(f"v{v['version']:<6} {v['content_hash'][:12]}  {who}, {v['published_at']}  "
                   f"(review: {v['review'].get('reviewer')}, {v['review'].get('review_date')})")


@rubric.command()
@click.argument("rubric_file", type=click.Path(exists=True, dir_okay=False, path_type=Path))
@URL
@TOKEN
def publish(rubric_file: Path, url: str, token: str) -> None:
    """Publish RUBRIC_FILE (YAML or JSON, the fields of rubric/lessons/L03-v2.yaml) as a new version of your course."""
    content = yaml.safe_load(rubric_file.read_text())
    row = _call(_client(url, token).publish_rubric, json.loads(json.dumps(content, default=str)))
    click.echo(f"published {row['lesson']} v{row['version']} ({row['content_hash'][:12]}) by {row['published_by']}")


@rubric.command()
@click.argument("course")
@click.argument("version")
@URL
@TOKEN
@LESSON
@click.option("--commit", is_flag=True, help="Write the regrade (old grades are kept); without it nothing is written.")
def regrade(course: str, version: str, url: str, token: str, lesson: str, commit: bool) -> None:
    """Preview regrading COURSE under VERSION, per student; --commit writes it."""
    client = _client(url, token)
    preview = _call(client.regrade_preview, course, version, lesson)
    click.echo(f"{preview['lesson']} v{preview['current_version']} -> v{preview['new_version']} "
               f"({preview['content_hash'][:12]}), course {course}")
    for old, changes in preview["rubric_changes"].items():
        click.echo(f"  from v{old}: " + ("; ".join(changes) or "no change"))
    for e in preview["entries"]:
        if e["skipped"]:
            click.echo(f"  {e['student']:<16} #{e['submission_id']:<6} stays: {e['skipped']}")
            continue
        click.echo(f"  {e['student']:<16} #{e['submission_id']:<6} {e['old_total']:g} -> {e['new_total']:g} / "
                   f"{e['max_total']:g}")
        for c in e["changed_items"]:
            click.echo(f"      {c['id']}: {c['old_verdict']} -> {c['new_verdict']}  ({c['why'].split(';')[0]})")
    if not commit:
        click.echo("preview only: nothing written (add --commit to regrade)")
        return
    done = _call(client.commit_regrade, course, version, preview["content_hash"], lesson)  # exactly what was shown
    click.echo(f"regrade #{done['id']} committed by {done['committed_by']} at {done['committed_at']}: "
               f"{done['regraded']} regraded, {done['changed']} changed, {len(done['skipped'])} left on their grade")
