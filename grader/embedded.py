"""`grader run`: the whole service on one laptop with no server to install.

SQLite database and a Celery broker on kombu's filesystem transport under DATA_DIR, a real Celery
worker process, the API on loopback, and the reconciler on a timer. Submits the example sheet, shows progress,
prints the grade summary and where the report is, then keeps serving until Ctrl-C (or exits after grading).
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import threading
import time
from collections.abc import Callable
from pathlib import Path

import click
import httpx

from grader.client import Client, load_sheet
from grader.core import warmth
from grader.core.db import migrate, new_session
from grader.core.states import CaseRunState, SubmissionState
from grader.dispatch import EMBEDDED_QUEUES, resend
from grader.reconcile import RECONCILE_EVERY_S, find_and_requeue
from grader.services.identity import accounts, sign_in_links
from grader.core.settings import settings

ROOT = Path(__file__).resolve().parent.parent
EXAMPLE_SHEET = ROOT / "examples" / "l03" / "reference.yaml"


def bootstrap() -> tuple[dict[str, str], str]:
    """Migrate the embedded database and issue fresh tokens for a demo course, and a sign-in link secret for its
    student (printed, never stored in clear; the student's earlier link stops working)."""
    migrate()
    with new_session() as session:
        course = accounts.get_or_create_course(session=session, name="demo")
        users = {role: accounts.get_or_create_user(session=session, course=course, name=role, role=role)
                 for role in ("student", "instructor")}
        tokens = {role: accounts.create_token(session=session, user=user) for role, user in users.items()}
        link, _ = sign_in_links.issue(session=session, user=users["student"])
        session.commit()
    return tokens, link


def start_worker(log_path: Path) -> subprocess.Popen:
    env = dict(os.environ, DATA_DIR=str(settings.data_dir.absolute()), DATABASE_URL=settings.database_url,
               BROKER_URL=settings.broker_url, ARTIFACTS_DIR=str(settings.artifacts_dir))
    # lazy: loads Celery and makes the filesystem broker's folders on import; `grader submit` imports this module too
    from worker.celery_app import worker_argv

    command = worker_argv(EMBEDDED_QUEUES, name="embedded@%h", heartbeat=False)
    return subprocess.Popen(command, cwd=ROOT, env=env, stdout=log_path.open("ab"), stderr=subprocess.STDOUT,
                            start_new_session=True)


# How long the worker's main process has for Celery's warm shutdown (a running case finishing, each slot closing its
# warm case process) before what is left of its process group is stopped.
WORKER_GRACE_S = 10.0


def stop_worker(worker: subprocess.Popen, *, grace_s: float = WORKER_GRACE_S) -> None:
    """Stop the worker and every process under it. start_worker made it the leader of its own process group, which
    its pool processes, their warm case processes and a kernel compile all stay in: SIGTERM to the main process
    first (the warm shutdown), then SIGTERM and at last SIGKILL to whatever is left of the group, also after the main
    process is gone (a warm case process busy warming up outlives the pool process that started it)."""
    if worker.poll() is None:
        worker.terminate()
        try:
            worker.wait(timeout=grace_s)
        except subprocess.TimeoutExpired:
            pass
    for sig in (signal.SIGTERM, signal.SIGKILL):
        try:
            os.killpg(worker.pid, sig)
        except ProcessLookupError:  # nothing of the group is left
            break
        deadline = time.monotonic() + 5.0
        while time.monotonic() < deadline:
            worker.poll()  # reaped, the main process no longer counts as the group's
            try:
                os.killpg(worker.pid, 0)
            except ProcessLookupError:
                break
            time.sleep(0.1)
    worker.wait()


def start_api(host: str, port: int) -> tuple[object, threading.Thread]:
    """uvicorn serving the app on a thread of this process, once it listens: the server and its thread."""
    import uvicorn  # lazy: only `grader run` serves; `grader submit` imports this module for follow/summary

    # proxy_headers off: uvicorn would trust X-Forwarded-For from 127.0.0.1, where every local client comes from; the
    # app trusts only settings.forwarded_allow_ips (none by default: grader.web.admission.TrustedProxies)
    server = uvicorn.Server(uvicorn.Config("grader.main:app", host=host, port=port, log_level="warning",
                                           proxy_headers=False))
    thread = threading.Thread(target=server.run, daemon=True)
    thread.start()
    while not server.started:
        if not thread.is_alive():
            raise click.ClickException(f"the API could not start on {host}:{port} (port in use?)")
        time.sleep(0.05)
    return server, thread


def reconcile_forever(stop: threading.Event) -> None:
    while not stop.wait(RECONCILE_EVERY_S):
        with new_session() as session:
            resend(find_and_requeue(session=session))


def show_warm_up(worker: subprocess.Popen, *, poll_s: float = 0.5, every_s: float = 30.0,
                 finished: Callable[[], bool] = lambda: False) -> None:
    """Say what the embedded worker does before it takes its first case, until it does (or `finished()`: a sheet
    whose runs were all reused needs no warm slot): compiling the simulation kernels (first run on a machine,
    minutes), then warming its case slots (seconds). A line when the phase changes, and one every `every_s` while it
    lasts, so a long first run is never silent."""
    said, said_at, started = None, 0.0, time.monotonic()
    while worker.poll() is None and not finished():
        compiling = warmth.compiling()
        workers = warmth.live()
        mine = next((w for w in workers or () if w.name.startswith("embedded@")), None)
        if workers is None or (mine is not None and mine.consuming):
            return
        if compiling is not None:
            elapsed = time.time() - compiling.started_at
            why = "first run on this machine" if compiling.first else "new engine version or backend"
            phase = f"compiling the simulation kernels ({why}, about {_minutes(compiling.estimate_s)}; once per machine)"
            progress = (f"{elapsed:.0f} s of about {compiling.estimate_s:.0f} s" if elapsed <= compiling.estimate_s
                        else f"{elapsed:.0f} s, longer than estimated (a busy machine compiles slower)")
        elif mine is not None:
            phase = f"warming {mine.slots} case slots (loading the kernels and building the lesson's scenes)"
            progress = f"{mine.warm} of {mine.slots} warm"
        else:
            phase, progress = "starting the worker", f"{time.monotonic() - started:.0f} s"
        now = time.monotonic()
        if phase != said or now - said_at >= every_s:
            click.echo(f"{phase} ... {progress}" if phase == said else f"{phase} ...")
            said, said_at = phase, now
        time.sleep(poll_s)


def _finished(client, submission_id: int) -> bool:
    try:
        return client.submission(submission_id)["status"] in (SubmissionState.GRADED, SubmissionState.FAILED)
    except (RuntimeError, httpx.HTTPError):  # a refused or failed look: `follow`, next, waits out and reports it
        return False


def _minutes(seconds: float) -> str:
    return f"{seconds:.0f} s" if seconds < 90 else f"{seconds / 60:.0f} minutes"


def follow(client, submission_id: int, total: int) -> dict:
    """Progress bar until failed, or graded with its lab check stored."""
    with click.progressbar(length=total, label=f"measuring {total} cases", show_pos=True) as bar:
        shown = 0

        def update(state: dict) -> None:
            nonlocal shown
            finished = state["progress"][CaseRunState.DONE] + state["progress"][CaseRunState.FAILED]
            completing = state["status"] == SubmissionState.GRADED and state.get("report_complete") is False
            bar.label = ("graded, evaluating the lab check" if completing
                         else f"{state['status']:8s} {state['progress']['running']} running")
            bar.update(finished - shown)
            shown = finished

        return client.wait(submission_id, poll_s=0.5, on_progress=update)


def summary(client, submission_id: int, state: dict, url: str, sign_in_link: str | None = None) -> Path:
    """Print the grade summary; write grade.json and case-runs.json under DATA_DIR/reports; return that folder.
    `sign_in_link`: the student's, printed beside the report page's URL."""
    folder = settings.data_dir.absolute() / "reports" / f"submission-{submission_id}"
    folder.mkdir(parents=True, exist_ok=True)
    runs = client.case_runs(submission_id)
    (folder / "case-runs.json").write_text(json.dumps(runs, indent=2, default=str))
    for run in runs:
        reused = f" (reused case run {run['reused_from_id']})" if run["reused_from_id"] else ""
        click.echo(f"  {run['name']:22s} {run['status']:6s} on {run['actual_backend'] or '-'}{reused}"
                   + (f": {run['error']}" if run["error"] else ""))
    if state["status"] != SubmissionState.GRADED:
        click.echo(f"submission {submission_id} {state['status']}: {state['error']}", err=True)
        return folder
    try:
        grade = client.grade(submission_id)
    except RuntimeError as exc:  # 409: its assignment withholds every score from this student yet
        click.echo(str(exc).splitlines()[0])
        return folder
    (folder / "grade.json").write_text(json.dumps(grade, indent=2, default=str))
    for item in grade["items"]:
        score = "  –  " if item["score"] is None else f"{item['score']:5.2f}"  # withheld by its assignment
        click.echo(f"  {item['id']:4s} {score}/{item['max_score']:<5.2f} {item['verdict']:10s} "
                   f"{item['feedback'][:90]}")
    click.echo(f"GRADE {grade['total']:g} / {grade['max_total']:g} (rubric {grade['rubric_lesson']} "
               f"v{grade['rubric_version']})" + (f"; {grade['pending']}" if grade.get("pending") else ""))
    click.echo(f"report: {folder}/grade.json and {url}/v1/submissions/{submission_id}/grade")
    if sign_in_link:
        click.echo(f"report page: {url}/submissions/{submission_id}\n"
                   f"  sign in first with the student's link (works once): {sign_in_link}")
    else:
        click.echo(f"report page: {url}/submissions/{submission_id} (sign in with the student token printed above)")
    click.echo(f"class dashboard: {url}/courses/demo/dashboard (sign in with the instructor token)")
    return folder


def _ignore_stops() -> None:
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, signal.SIG_IGN)


def _stop_once(signum, frame) -> None:
    """Ctrl-C or SIGTERM: stop (KeyboardInterrupt), once; a second one while stopping is ignored."""
    _ignore_stops()
    raise KeyboardInterrupt


def run(*, host: str, port: int, sheet: Path, exit_after_grading: bool) -> int:
    """The embedded service until graded (`exit_after_grading`) or Ctrl-C / SIGTERM: 0 graded, 1 failed, 130
    stopped. However it ends (an error too), every process and thread it started is stopped first: the worker with
    its warm case processes (stop_worker), the API's uvicorn and the reconciler."""
    handlers = {sig: signal.getsignal(sig) for sig in (signal.SIGINT, signal.SIGTERM)}
    for sig in handlers:  # SIGTERM stops like Ctrl-C from the start: before the first grade it left the worker running
        signal.signal(sig, _stop_once)
    worker, server, threads, stop = None, None, [], threading.Event()
    try:
        settings.data_dir.mkdir(parents=True, exist_ok=True)
        click.echo(f"embedded service: database {settings.database_url}, broker {settings.broker_url}")
        tokens, link = bootstrap()
        worker = start_worker(settings.data_dir / "worker.log")
        server, serving = start_api(host, port)
        threads.append(serving)
        url = f"http://{host}:{port}"
        threads.append(threading.Thread(target=reconcile_forever, args=(stop,), daemon=True))
        threads[-1].start()
        click.echo(f"API at {url} (docs {url}/docs); worker log {settings.data_dir.absolute() / 'worker.log'}")
        click.echo(f"student token: {tokens['student']}\ninstructor token: {tokens['instructor']}")
        client = Client(url, tokens["student"])
        created = client.submit(load_sheet(sheet))
        click.echo(f"submitted {sheet} as submission {created['id']} ({created['progress']['total']} case runs)")
        show_warm_up(worker, finished=lambda: _finished(client, created["id"]))
        state = follow(client, created["id"], created["progress"]["total"])
        summary(client, created["id"], state, url, sign_in_link=f"{url}{sign_in_links.PATH}{link}")
        if not exit_after_grading:
            click.echo(f"serving at {url} until Ctrl-C")
            while True:
                time.sleep(3600)
        return 0 if state["status"] == SubmissionState.GRADED else 1
    except KeyboardInterrupt:
        return 130
    finally:
        _ignore_stops()  # however it ended: a Ctrl-C now must not cut the stopping short, which is bounded
        stop.set()
        if server is not None:
            server.should_exit = True
        if worker is not None:
            stop_worker(worker)
        for thread in threads:
            thread.join(timeout=10)
        for sig, handler in handlers.items():
            signal.signal(sig, handler)
