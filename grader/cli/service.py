"""`grader admin|worker|reconcile|submit|run`: operate the grading service from the command line."""

from __future__ import annotations

import os
import socket
import statistics
import sys
import time
from pathlib import Path

import click

from grader.core.states import Backend, SubmissionState, values
from grader.core.settings import settings


@click.group()
def admin() -> None:
    """Schema migrations, courses, users and API tokens."""


@admin.command()
def migrate() -> None:
    """Upgrade the database (DATABASE_URL) to the newest schema."""
    from grader.core.db import migrate as upgrade  # lazy: SQLAlchemy (~0.5 s) stays off `grader --help`

    upgrade()
    click.echo(f"schema up to date: {settings.database_url.split('@')[-1]}")


@admin.command()
@click.argument("course", required=False)
@click.argument("name", required=False)
@click.option("--role", type=click.Choice(["student", "instructor", "auditor"]), help="The new user's role.")
@click.option("--expires-in", type=click.IntRange(1, 3650), metavar="DAYS",
              help=f"The new token expires after DAYS days (default {settings.token_lifetime_days}).")
@click.option("--revoke", metavar="TOKEN_OR_ID", help="Revoke this token (or the token with this id from --list) "
              "and end the page sessions it opened.")
@click.option("--list", "list_tokens", is_flag=True, help="List NAME's tokens: id, created, expiry, revoked.")
def token(course: str | None, name: str | None, role: str | None, expires_in: int | None, revoke: str | None,
          list_tokens: bool) -> None:
    """Create COURSE and user NAME if needed, and print a new API token for them (shown only once); or --revoke a
    token; or --list NAME's tokens."""
    # lazy: SQLAlchemy (~0.5 s) stays off `grader --help`; only the database commands load it
    from grader.core.db import new_session
    from grader.services.identity import accounts
    from grader.services.errors import DomainError

    if revoke is not None:
        if course or name or role or expires_in or list_tokens:
            raise click.UsageError("--revoke takes only the token or its id: no COURSE, NAME, --role, --expires-in "
                                   "or --list")
        with new_session() as session:
            try:
                row = accounts.revoke_token(session=session, token_or_id=revoke)
            except DomainError as exc:
                raise click.ClickException(exc.detail) from None
            session.commit()
            click.echo(f"token {row.id} of {row.user.name} revoked at {row.revoked_at:%Y-%m-%d %H:%M} UTC")
        return
    if not (course and name) or (role is None and not list_tokens):
        raise click.UsageError("give COURSE NAME --role ROLE to create a token, COURSE NAME --list to list a user's, "
                               "or --revoke TOKEN_OR_ID")
    with new_session() as session:
        if list_tokens:
            try:
                rows = accounts.tokens_of(session=session, course=course, name=name)
            except DomainError as exc:
                raise click.ClickException(exc.detail) from None
            for row in rows:
                expires = f"{row.expires_at:%Y-%m-%d %H:%M}" if row.expires_at else "never"
                revoked = f"  revoked {row.revoked_at:%Y-%m-%d %H:%M}" if row.revoked_at else ""
                click.echo(f"{row.id}  created {row.created_at:%Y-%m-%d %H:%M}  expires {expires}{revoked}")
            return
        course_row = accounts.get_or_create_course(session=session, name=course)
        try:
            user = accounts.get_or_create_user(session=session, course=course_row, name=name, role=role)
        except ValueError as exc:
            raise click.ClickException(str(exc)) from None
        clear = accounts.create_token(session=session, user=user, expires_in_days=expires_in)
        session.commit()
    click.echo(clear)


@click.command()
@click.option("--queue", "queues", multiple=True, default=("cpu", "grade"), show_default=True,
              type=click.Choice([*values(Backend), "grade"]), help="Queues to consume (repeatable).")
@click.option("--loglevel", default="info", show_default=True)
@click.option("--healthy", is_flag=True,
              help="Run no worker: exit 0 if this host's worker of these queues answers a ping and takes cases (every "
                   "case slot warm), else 1, saying which (the container's health check).")
def worker(queues: tuple[str, ...], loglevel: str, healthy: bool) -> None:
    """Run a Celery worker: WORKER_CONCURRENCY case slots (default one per core), each holding its own warm Genesis
    process; it takes cases once every slot is warm."""
    if healthy:
        from grader.ops import worker_health  # lazy: SQLAlchemy and Celery stay off `grader --help`

        ok, said = worker_health(f"{'-'.join(queues)}@{socket.gethostname()}")
        if not ok:
            raise click.ClickException(said)
        click.echo(said)
        return
    # lazy: loads Celery and makes the filesystem broker's folders on import; only `grader worker` needs it
    from worker.celery_app import worker_argv

    os.execv(sys.executable, worker_argv(queues, name=f"{'-'.join(queues)}@%h", loglevel=loglevel))


@click.command()
@click.option("--every", type=float, default=0.0, help="Repeat every N seconds, pass start to pass start (0: once).")
@click.option("--healthy-within", type=float, default=None, metavar="SECONDS",
              help="Reconcile nothing: exit 0 if this host's reconciler finished a pass within SECONDS, else 1 (the "
                   "container's health check).")
def reconcile(every: float, healthy_within: float | None) -> None:
    """Re-send case runs left queued or running past their lease, and stuck gradings."""
    # lazy: SQLAlchemy stays off `grader --help`; and looked up per call (tests/grader/core/test_reconcile.py patches them)
    from grader.core.db import new_session
    from grader.dispatch import broker_kept_marker, held_tasks, resend
    from grader.reconcile import UNKNOWN_RETRY_S, beating_hosts, find_and_requeue, last_pass_age_s, mark_pass

    if healthy_within is not None:
        age = last_pass_age_s()
        if age is None or age > healthy_within:
            said = "never finished a pass" if age is None else f"last finished a pass {age:.0f} s ago"
            raise click.ClickException(f"unhealthy: the reconciler {said} (limit {healthy_within:g} s)")
        click.echo(f"healthy: last pass {age:.0f} s ago")
        return

    marker_left = lost_seen = False
    while True:
        started = time.monotonic()
        liveness = held_tasks()  # asked before reading the runs, so a task it reports held is never judged lost
        beating = beating_hosts()  # likewise: a worker that claims a run after this is not judged by it
        broker_lost = lost_seen
        if liveness is not None and not settings.broker_url.startswith("filesystem"):
            kept = broker_kept_marker()
            # Only a marker this process left and saw can be missed: the first pass only leaves it.
            broker_lost, marker_left = broker_lost or (marker_left and kept is False), marker_left or kept is not None
        lost_seen = broker_lost and liveness is None  # kept for a pass that can act on it
        with new_session() as session:
            todo = find_and_requeue(session=session, liveness=liveness, broker_lost=broker_lost, beating=beating)
        mark_pass()
        resend(todo)
        if todo.case_runs or todo.gradings:
            click.echo(f"re-sent {len(todo.case_runs)} case runs, {len(todo.gradings)} gradings")
        if not every:
            return
        # A broker that did not answer (restarting) is asked again soon: what it lost is re-sent seconds after it
        # is back, not a whole interval later. The embedded broker never answers; there the interval stands.
        unknown = liveness is None and not settings.broker_url.startswith("filesystem")
        deadline = started + (min(every, UNKNOWN_RETRY_S) if unknown else every)
        # Meanwhile the marker is watched (one cheap read every UNKNOWN_RETRY_S): a broker that lost its messages
        # is reconciled at once, not at the next pass.
        while (left := deadline - time.monotonic()) > 0:
            time.sleep(min(left, UNKNOWN_RETRY_S) if marker_left else left)
            if marker_left and broker_kept_marker() is False:
                lost_seen = True
                break


@click.command("submit")
@click.argument("sheet_file", type=click.Path(exists=True, dir_okay=False, path_type=Path))
@click.option("--url", envvar="GRADER_URL", default="http://127.0.0.1:8000", show_default=True)
@click.option("--token", envvar="GRADER_TOKEN", required=True, help="API token (or GRADER_TOKEN).")
@click.option("--backend", type=click.Choice(values(Backend)), help="Run every case on this backend (staff only).")
@click.option("--force-rerun", is_flag=True, help="Measure afresh instead of reusing stored measurements (staff only).")
@click.option("--no-wait", is_flag=True, help="Submit and print the id without following progress.")
@click.option("--assignment", "assignment_id", type=int, default=None,
              help="Submit to this assignment of your course (the sheet answers exactly its items).")
def submit(sheet_file, url: str, token: str, backend: str | None, force_rerun: bool, no_wait: bool,
           assignment_id: int | None) -> None:
    """Submit SHEET_FILE (YAML or JSON) to a running grading service and follow it to its grade."""
    # lazy: httpx and SQLAlchemy stay off `grader --help`; Client looked up per call (test_assignment_cli patches it)
    from grader.client import Client, load_sheet
    from grader.embedded import follow, summary
    from rubric.sheet_files import SheetTextError  # lazy: numpy and pydantic (rubric) stay off `grader --help`

    client = Client(url, token)
    options = {"force_rerun": force_rerun, **({"backend": backend} if backend else {}),
               **({"assignment_id": assignment_id} if assignment_id else {})}
    try:
        sheet = load_sheet(sheet_file)
    except SheetTextError as exc:  # nothing sent: the field and the rule, as the sheet page's import says them
        raise click.ClickException(f"{sheet_file}: {exc.field}: {exc.rule}") from None
    try:
        created = client.submit(sheet, **options)
    except RuntimeError as exc:
        raise click.ClickException(str(exc)) from None
    progress = created["progress"]
    if created["status"] == SubmissionState.GRADED:  # a checkpoint sheet on the lesson's cases as already measured
        click.echo(f"submission {created['id']}: graded at once, no case run ({progress['done']} stored "
                   f"measurements of the lesson's own cases reused)")
    else:
        click.echo(f"submission {created['id']}: {progress['queued']} case runs queued")
    if created["attempt"]:
        from grader.services.setup.assignments import late_text  # lazy: SQLAlchemy stays off `grader --help`

        click.echo(f"assignment {created['assignment_id']}, attempt {created['attempt']}, "
                   f"{late_text(created['late_seconds'])}")
    if no_wait:
        return
    state = created if created["status"] == SubmissionState.GRADED else follow(client, created["id"], progress["total"])
    summary(client, created["id"], state, url)
    if state["status"] != SubmissionState.GRADED:
        sys.exit(1)


@click.command("run")
@click.option("--host", default="127.0.0.1", show_default=True)
@click.option("--port", default=8000, show_default=True)
@click.option("--sheet", type=click.Path(exists=True, dir_okay=False, path_type=Path),
              default=None, help="Sheet to submit (default: examples/l03/reference.yaml).")
@click.option("--exit-after-grading", is_flag=True, help="Stop once the example sheet is graded.")
def run(host: str, port: int, sheet, exit_after_grading: bool) -> None:
    """Run the whole service embedded (SQLite, local worker, no servers), grade the example sheet, keep serving."""
    from grader import embedded  # lazy: SQLAlchemy and the embedded service stay off `grader --help`

    sys.exit(embedded.run(host=host, port=port, sheet=sheet or embedded.EXAMPLE_SHEET,
                          exit_after_grading=exit_after_grading))




@click.command()
@click.option("--timeout", "timeout_s", type=float, default=1.0, show_default=True,
              help="Seconds to wait for workers to answer.")
def status(timeout_s: float) -> None:
    """What an operator watches: queues, live workers, case runs by state, failures by reason, durations."""
    # lazy: SQLAlchemy and prometheus_client stay off `grader --help`
    from grader.core.db import new_session
    from grader.ops import service_status

    with new_session() as session:
        s = service_status(session, timeout_s=timeout_s)
    if s.broker_error:
        click.echo(f"broker: UNREACHABLE ({s.broker_error})")
    click.echo("queues:   " + ", ".join(f"{q} {'?' if n is None else n}" for q, n in s.queues.items()))
    if s.workers is None:
        click.echo("workers:  not knowable on the embedded broker (one local worker on cpu, grade)")
    else:
        click.echo(f"workers:  {len(s.workers)} live" + "".join(f"\n  {name}: {', '.join(queues)}"
                                                             for name, queues in s.workers.items()))
    for w in s.warmth or []:
        click.echo(f"  {w['worker']}: {w['warm']} of {w['slots']} case slots warm, " + (
            f"taking cases (warmed up in {w['warm_s']:.1f} s)" if w["consuming"] else
            f"WARMING UP for {w['warming_for_s']:.0f} s, no case taken yet"))
    if s.warmth is not None and s.last_warm_up_s is not None:
        click.echo(f"last warm-up: {s.last_warm_up_s:.1f} s from a worker's start to every slot warm")
    click.echo("submissions: " + (", ".join(f"{k} {v}" for k, v in sorted(s.submissions_by_state.items())) or "none"))
    for backend, states in sorted(s.case_runs_by_state.items()):
        click.echo(f"case runs on {backend}: " + ", ".join(f"{k} {v}" for k, v in sorted(states.items())))
    click.echo("failures: " + (", ".join(f"{k} {v}" for k, v in sorted(s.failures_by_reason.items())) or "none"))
    click.echo(f"stuck:    {s.stuck_case_runs} case runs past their lease")
    click.echo(f"completing: {s.grades_completing} grades stored whose lab check is being evaluated")
    if s.durations_s:
        q = statistics.quantiles(s.durations_s, n=20) if len(s.durations_s) > 1 else s.durations_s * 19
        click.echo(f"measured case runs: {len(s.durations_s)}, median {statistics.median(s.durations_s):.1f} s, "
                   f"p95 {q[-1]:.1f} s")


COMMANDS = (admin, worker, reconcile, submit, run, status)
