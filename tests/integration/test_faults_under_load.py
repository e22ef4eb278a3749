"""Faults during load, with the shipped leases and reconciler interval (issue 12, part 3).

Redis + PostgreSQL: 20 submissions (most sharing the baseline cases, so the load stays bounded) on the API, one
Celery worker and `grader reconcile --every RECONCILE_EVERY_S`, each server this test's own so it can be restarted.
During the load the worker is SIGKILLed mid-case twice (a fresh one started each time), Redis is restarted without
persistence and PostgreSQL is restarted. The embedded default (`grader run`: SQLite, filesystem broker) gets 4
submissions and its worker killed mid-case. Afterwards nothing is lost, graded twice or left queued/running, and
every delivery of every case run is in its events. Printed: seconds from a fresh worker being ready to the killed
case running again and from the broker being back to the lost runs re-sent and running (the issue's target: 30 s
each), and to the first state change after the PostgreSQL restart.
"""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import time
import uuid
from pathlib import Path

import pytest
from sqlalchemy import func, select
from sqlalchemy.exc import OperationalError
from sqlalchemy.orm import Session

from grader.core.lifecycle import FINISHED_WHEN_MEASURED
from grader.core.models import CaseRun, Event, Grade, Submission, utcnow
from tests import services
from tests.factories import create_people, reference_sheet
from tests.integration.helpers import wait_until
from tests.private_services import PrivatePostgres, PrivateRedis

pytestmark = [pytest.mark.integration, pytest.mark.slow]

TARGET_S = 30.0  # the target for each recovery figure
LOAD_LIMIT_S = 600  # safety stop for the whole load; no assertion about speed rides on it


def _sheet(table_friction: float | None = None) -> dict:
    """The reference sheet, or with another table friction: a case of its own, measured for real."""
    sheet = reference_sheet()
    if table_friction is not None:
        sheet["configs"]["table_exercise"]["table"]["friction"] = table_friction
        sheet["configs"]["table_exercise"]["name"] = f"table-{table_friction:.2f}"
    return sheet


def _descendants(pid: int) -> list[int]:
    found = []
    for child in services.children(pid):
        found += [child, *_descendants(child)]
    return found


def _kill_tree(pid: int) -> None:
    """SIGKILL a worker and everything under it (pool process, warm case process): nothing gets to clean up."""
    for victim in [pid, *_descendants(pid)]:
        try:
            os.kill(victim, signal.SIGKILL)
        except ProcessLookupError:
            pass


def _start_worker(env: dict, name: str, queues: tuple[str, ...], log: Path, *, heartbeat: bool = True):
    """The shipped worker command (`worker_argv`); returns the process and the UTC time it took cases: once its
    case slots are warm (worker.warm_gate: until then it takes none, and the runs wait in the broker)."""
    from tools.harness.processes import WARM_UP_LIMIT_S
    from worker.celery_app import worker_argv
    from worker.warm_gate import OPENED

    proc = subprocess.Popen(worker_argv(queues, name=f"{name}@%h", heartbeat=heartbeat), cwd=services.ROOT, env=env,
                            stdout=log.open("ab"), stderr=subprocess.STDOUT, start_new_session=True)
    services.wait_for(lambda: " ready." in log.read_text(errors="replace"), "celery worker", proc, log)
    services.wait_for(lambda: OPENED in log.read_text(errors="replace"), "celery worker's warm-up", proc, log,
                      limit_s=WARM_UP_LIMIT_S)
    return proc, utcnow()


class Db:
    """Reads for the test, retried across the PostgreSQL restart (the test's own connections are cut too)."""

    def __init__(self, url: str):
        from grader.core.db import make_engine

        self.engine = make_engine(url)

    def read(self, fn):
        deadline = time.monotonic() + services.STARTUP_LIMIT_S
        while True:
            try:
                with Session(self.engine) as session:
                    return fn(session)
            except OperationalError:
                if time.monotonic() > deadline:
                    raise
                time.sleep(0.5)

    def runs(self) -> list[CaseRun]:
        return self.read(lambda s: s.scalars(select(CaseRun).order_by(CaseRun.id)).all())

    def events(self, **where) -> list[Event]:
        query = select(Event).filter_by(**where).order_by(Event.id)
        return self.read(lambda s: s.scalars(query).all())

    def wait(self, predicate, what: str, limit_s: float = LOAD_LIMIT_S):
        return wait_until(predicate, what, limit_s)


def _mid_case(db: Db, worker_pid: int, artifacts: Path) -> CaseRun | None:
    """A run held by this worker whose case process has its spec: killed now, it dies in the middle of a case."""
    pool = set(services.children(worker_pid))
    for run in db.runs():
        if run.status == "running" and run.worker_pid in pool and \
                (artifacts / "case-runs" / str(run.id) / f"try-{run.tries}" / "spec.json").exists():
            return run
    return None


def _kill_mid_case(db: Db, worker, artifacts: Path) -> tuple[CaseRun, object]:
    victim = db.wait(lambda: _mid_case(db, worker.pid, artifacts), "a case run in the middle of its case")
    _kill_tree(worker.pid)
    worker.wait()
    return victim, utcnow()


def _running_again(db: Db, victim: CaseRun) -> Event:
    """The killed run's next claim (a 'running' event with a later try), or, where another run measured the same case
    first while the killed one waited re-sent in the queue, its finishing there (grader.core.lifecycle.finish_alike:
    a 'done' after its 'requeued', never claimed again)."""
    def found():
        mine = db.events(case_run_id=victim.id)
        again = next((e for e in mine if e.state == "running" and e.detail
                      and e.detail.endswith(f"try {victim.tries + 1}")), None)
        requeued = next((e for e in mine if e.state == "requeued"), None)
        finished = next((e for e in mine if e.state == "done" and requeued is not None and e.id > requeued.id
                         and e.detail and FINISHED_WHEN_MEASURED in e.detail), None)
        return again or finished
    return db.wait(found, f"case run {victim.id} running again (or finished in the queue on another run's measurement)")


def _wait_finished(db: Db, submission_ids: list[int], logs: Path) -> None:
    finished = select(func.count()).select_from(Submission).where(
        Submission.id.in_(submission_ids), Submission.status.in_(("graded", "failed")))
    try:
        db.wait(lambda: db.read(lambda s: s.scalar(finished)) == len(submission_ids), "every submission finished")
    except AssertionError as gave_up:
        raise AssertionError(f"{gave_up}\n{_where_it_stands(db, submission_ids, logs)}") from None


def _where_it_stands(db: Db, submission_ids: list[int], logs: Path) -> str:
    """What a wait that gave up leaves to read: each unfinished submission, its runs and their last events, and the
    last lines of every process's log (CI keeps nothing else of this test's servers)."""
    def read(session):
        subs = session.scalars(select(Submission).where(Submission.id.in_(submission_ids),
                                                        Submission.status.not_in(("graded", "failed")))).all()
        lines = []
        for sub in subs:
            lines.append(f"submission {sub.id}: {sub.status}")
            for run in session.scalars(select(CaseRun).where(CaseRun.submission_id == sub.id)).all():
                events = session.scalars(select(Event).where(Event.case_run_id == run.id).order_by(Event.id)).all()
                trail = ", ".join(f"{e.state}@{e.at:%H:%M:%S}" for e in events[-6:])
                lines.append(f"  run {run.id} {run.name}: {run.status} tries={run.tries} delivery={run.delivery} "
                             f"worker={run.worker} lease_until={run.lease_until} [{trail}]")
        return lines
    lines = db.read(read)
    for log in sorted(logs.glob("*.log")):
        tail = log.read_text(errors="replace").splitlines()[-25:]
        lines += [f"--- {log.name} (last lines)", *tail]
    return "\n".join(lines)


def _check_outcome(db: Db, submission_ids: list[int]) -> None:
    """Nothing lost, graded twice or stuck; every delivery of every case run recorded."""
    def read(session):
        subs = session.scalars(select(Submission).where(Submission.id.in_(submission_ids))).all()
        grades = dict(session.execute(select(Grade.submission_id, func.count()).group_by(Grade.submission_id)).all())
        runs = session.scalars(select(CaseRun).where(CaseRun.submission_id.in_(submission_ids))).all()
        events = session.scalars(select(Event).where(Event.submission_id.in_(submission_ids)).order_by(Event.id)).all()
        return subs, grades, runs, events

    subs, grades, runs, events = db.read(read)
    assert sorted(s.id for s in subs) == sorted(submission_ids), "a submission was lost"
    not_graded = [(s.id, s.status, s.error) for s in subs if s.status != "graded"]
    assert not not_graded, not_graded
    assert all(grades.get(s.id) == 1 for s in subs), {s.id: grades.get(s.id) for s in subs}
    graded_events = {s.id: 0 for s in subs}
    for e in events:
        if e.case_run_id is None and e.state == "graded":
            graded_events[e.submission_id] += 1
    assert set(graded_events.values()) == {1}, graded_events
    unfinished = [(r.id, r.status, r.error) for r in runs if r.status != "done"]
    assert runs and not unfinished, unfinished
    for run in runs:
        mine = [e.state for e in events if e.case_run_id == run.id]
        if run.tries == 0:  # never claimed by a worker: finished on a stored measurement in the POST, or in the queue
            # when another run measured its case (grader.core.lifecycle.finish_alike); one whose message was lost with
            # the broker may have been re-sent before that (one "requeued" a re-sending), never run
            found = [e.detail for e in events if e.case_run_id == run.id and e.state == "done"]
            resent = mine.count("requeued")
            assert [s for s in mine if s != "requeued"] == ["queued", "done"] and run.reused_from_id is not None, (
                run.id, mine, run.reused_from_id)
            assert resent == run.delivery - 1, (run.id, run.delivery, mine)
            assert len(found) == 1 and ("(found when submitted)" in found[0]
                                        or FINISHED_WHEN_MEASURED in found[0]), (run.id, found)
            assert not resent or FINISHED_WHEN_MEASURED in found[0], (run.id, mine, found)
            continue
        assert mine.count("running") == run.tries, (run.id, run.tries, mine)
        assert mine.count("requeued") == run.delivery - 1, (run.id, run.delivery, mine)
        assert mine[-1] == "done", (run.id, mine)


def _since(at, then) -> float:
    return (at - then).total_seconds()


def test_on_redis_a_resent_run_goes_first_and_an_emptied_broker_is_noticed(tmp_path):
    """The two broker facts the recovery rests on, on a real Redis: a re-sent run is read before the runs queued
    earlier, and the marker message is gone after a restart without persistence (and only then)."""
    redis = PrivateRedis(tmp_path)
    redis.start()
    env = dict(os.environ, BROKER_URL=redis.url, PYTHONPATH=str(services.ROOT))

    def run(code: str) -> str:
        done = subprocess.run([sys.executable, "-c", f"from grader import dispatch\n{code}"], cwd=services.ROOT,
                              env=env, capture_output=True, text=True, timeout=120)
        assert done.returncode == 0, done.stderr[-3000:]
        return done.stdout.strip()

    try:
        read = run("from worker.celery_app import app\n"
                   "for run_id in (1, 2): dispatch.send_case_run(run_id, 1, 'cpu')\n"
                   "dispatch.send_case_run(3, 2, 'cpu', priority=dispatch.REQUEUED_PRIORITY)\n"
                   "dispatch.send_case_run(4, 2, 'cpu', priority=dispatch.RERUN_PRIORITY)\n"
                   "with app.connection_for_read() as c:\n"
                   "    q = c.SimpleQueue('cpu')\n"
                   "    print([tuple(q.get(timeout=5).payload[0]) for _ in range(4)])")
        assert read == "[(4, 2), (3, 2), (1, 1), (2, 1)]"
        marker = "print(dispatch.broker_kept_marker(), dispatch.broker_kept_marker())"
        assert run(marker) == "False True"  # never left yet: left now, then seen
        assert run(marker) == "True True"  # another process sees it too
        redis.restart()
        assert run(marker) == "False True"  # gone with the restart, left again
        redis.stop()
        assert run("print(dispatch.broker_kept_marker())") == "None"  # no broker, no answer
    finally:
        redis.stop()


def test_faults_under_load_on_redis_and_postgres(tmp_path, kernel_cache_filled):
    from grader.client import Client
    from grader.core.db import migrate
    from grader.reconcile import RECONCILE_EVERY_S

    redis, postgres = PrivateRedis(tmp_path), PrivatePostgres()
    redis.start()
    postgres.start()
    procs: list[subprocess.Popen] = []
    try:
        migrate(postgres.url)
        db = Db(postgres.url)
        with Session(db.engine) as session:
            tokens = create_people(session, course="l03-faults", other_course="other")
            session.commit()
        data_dir, logs = tmp_path / "data", tmp_path / "logs"
        logs.mkdir()
        # The shipped settings, except the per-token submission rate and the cap on a student's waiting runs: one
        # test is a whole class at the deadline.
        env = {k: v for k, v in os.environ.items() if not k.endswith(("_S", "_URL"))} | dict(
            DATABASE_URL=postgres.url, BROKER_URL=redis.url, DATA_DIR=str(data_dir), PYTHONPATH=str(services.ROOT),
            RATE_LIMIT_SUBMISSIONS="1000/minute", STUDENT_WAITING_RUNS_MAX="1000") | services.private_kernel_cache(tmp_path)
        artifacts = data_dir / "artifacts"
        port = services.free_port()
        procs.append(services.start_api(env, port, logs / "api.log"))
        reconciler = subprocess.Popen(
            [sys.executable, "-m", "grader.cli", "reconcile", "--every", str(RECONCILE_EVERY_S)], cwd=services.ROOT,
            env=env, stdout=(logs / "reconciler.log").open("ab"), stderr=subprocess.STDOUT, start_new_session=True)
        procs.append(reconciler)
        worker, _ = _start_worker(env, "w1", ("cpu", "grade"), logs / "worker-1.log")
        procs.append(worker)
        clients = [Client(f"http://127.0.0.1:{port}", tokens[who]) for who in ("alice", "bob")]
        staff = Client(f"http://127.0.0.1:{port}", tokens["prof"])  # force_rerun is a staff power
        submitted: list[int] = []

        def submit(sheets: list[dict], **options) -> None:
            for sheet in sheets:
                submitted.append(clients[len(submitted) % 2].submit(sheet, **options)["id"])

        figures: dict[str, float] = {}

        # Wave A: the baseline measured once, five students' own table frictions. Kill 1 lands on the fresh
        # worker's first case (its warm case process is still starting).
        submit([_sheet(), *(_sheet(0.31 + i / 100) for i in range(5))])
        victim, _ = _kill_mid_case(db, worker, artifacts)
        worker, ready_at = _start_worker(env, "w2", ("cpu", "grade"), logs / "worker-2.log")
        procs.append(worker)
        again = _running_again(db, victim)
        figures["kill 1: ready -> running again"] = _since(again.at, ready_at)

        # Wave B, then Redis restarted (no persistence) with its runs queued, and wave C sent at once after it:
        # the cpu queue is not empty, yet the messages of wave B are gone. The restart lands while the worker runs
        # ordinary cases, not its first one (the warm case process starting takes tens of seconds, and with one slot
        # nothing else moves meanwhile).
        db.wait(lambda: next(r for r in db.runs() if r.id == victim.id).status == "done", "the killed case done")
        submit([_sheet(), _sheet(0.36), _sheet(0.37), _sheet(), _sheet(0.38), _sheet()])
        queued_before = {r.id for r in db.runs() if r.status == "queued"}
        redis.restart()
        broker_back = utcnow()
        submit([_sheet(), _sheet(0.39), _sheet(), _sheet(0.40)])

        def resent_and_running():
            requeued = [e for e in db.events(state="requeued") if e.at > broker_back and e.case_run_id in queued_before]
            return requeued and next((e for e in db.events(state="running") if e.at > requeued[0].at and
                                      e.case_run_id in {r.case_run_id for r in requeued}), None)

        moving = db.wait(resent_and_running, "a run lost with the broker re-sent and running")
        resent = min(e.at for e in db.events(state="requeued") if e.at > broker_back)
        figures["redis: back -> lost runs re-sent"] = _since(resent, broker_back)
        figures["redis: back -> first re-sent run running"] = _since(moving.at, broker_back)

        # PostgreSQL restarted under the load: every connection of the API, worker and reconciler is cut.
        postgres.restart()
        db_back = utcnow()
        first = db.wait(lambda: next((e for e in db.events() if e.at > db_back), None), "a state change")
        figures["postgres: back -> first state change"] = _since(first.at, db_back)

        # Wave D with one forced re-measurement of every case, and kill 2 in the middle of one.
        submit([_sheet(), _sheet(0.41), _sheet()])
        submitted.append(staff.submit(_sheet(), force_rerun=True)["id"])
        victim, _ = _kill_mid_case(db, worker, artifacts)
        worker, ready_at = _start_worker(env, "w3", ("cpu", "grade"), logs / "worker-3.log")
        procs.append(worker)
        again = _running_again(db, victim)
        figures["kill 2: ready -> running again"] = _since(again.at, ready_at)

        assert len(submitted) >= 20
        _wait_finished(db, submitted, logs)
        print(f"\nfaults under load, {len(submitted)} submissions:")
        for name, seconds in figures.items():
            print(f"  {name}: {seconds:.1f} s")
        _check_outcome(db, submitted)
        # The targets: a killed case running again, lost runs re-sent. A re-sent run starting, and the first
        # state change after the PostgreSQL restart, wait for the case the one worker has in flight (it survives both
        # restarts): they say how long that case ran (28 s and 44 s seen on the loaded 2-core machine), not how long
        # recovery took, so they are printed, not held to the target.
        held = ("kill 1: ready -> running again", "kill 2: ready -> running again", "redis: back -> lost runs re-sent")
        slow = {name: figures[name] for name in held if figures[name] > TARGET_S}
        assert not slow, f"recovery slower than {TARGET_S:g} s: {slow}"
    finally:
        for proc in reversed(procs):
            services.stop(proc)
        postgres.stop()
        redis.stop()


def test_faults_on_the_embedded_default(tmp_path, kernel_cache_filled):
    """`grader run` (SQLite, filesystem broker, its own reconciler) with 4 submissions; its worker SIGKILLed
    mid-case and a fresh one started: the killed case runs again, and everything is graded once."""
    from grader.client import Client
    from grader.dispatch import EMBEDDED_QUEUES

    data_dir = tmp_path / "data"
    env = {k: v for k, v in os.environ.items() if not k.endswith(("_S", "_URL")) and k != "ARTIFACTS_DIR"} | dict(
        DATA_DIR=str(data_dir), PYTHONPATH=str(services.ROOT), PYTHONUNBUFFERED="1",
        STUDENT_WAITING_RUNS_MAX="1000",  # one student sends the four sheets at once; the cap has its own test
    ) | services.private_kernel_cache(tmp_path)
    port = services.free_port()
    out = tmp_path / "grader-run.log"
    service = subprocess.Popen([sys.executable, "-m", "grader.cli", "run", "--port", str(port)], cwd=services.ROOT,
                               env=env, stdout=out.open("ab"), stderr=subprocess.STDOUT, start_new_session=True)
    fresh = None
    try:
        tokens = _wait_tokens(service, out)
        db = Db(f"sqlite:///{data_dir / 'grader.db'}")
        client = Client(f"http://127.0.0.1:{port}", tokens["student"])
        submitted = [1] + [client.submit(_sheet(friction))["id"] for friction in (0.33, 0.34, 0.35)]
        worker_pid = next(pid for pid in services.children(service.pid)
                          if b"celery" in Path(f"/proc/{pid}/cmdline").read_bytes())

        class Proc:  # the embedded worker is grader run's child, not ours: kill it by pid
            pid = worker_pid

            @staticmethod
            def wait():
                while Path(f"/proc/{worker_pid}").exists() and "Z" not in _proc_state(worker_pid):
                    time.sleep(0.05)

        victim, killed_at = _kill_mid_case(db, Proc, data_dir / "artifacts")
        fresh, ready_at = _start_worker(env, f"embedded-{uuid.uuid4().hex[:4]}", EMBEDDED_QUEUES,
                                        tmp_path / "worker-fresh.log", heartbeat=False)
        again = _running_again(db, victim)
        ready_to_running = _since(again.at, ready_at)
        _wait_finished(db, submitted, tmp_path)
        print(f"\nembedded, {len(submitted)} submissions: worker killed {_since(again.at, killed_at):.1f} s before "
              f"its case ran again; ready -> running again {ready_to_running:.1f} s")
        _check_outcome(db, submitted)
        assert ready_to_running <= TARGET_S, f"ready -> running again took {ready_to_running:.1f} s"
    finally:
        if fresh is not None:
            services.stop(fresh)
        services.stop(service)


def _proc_state(pid: int) -> str:
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return "Z"


def _wait_tokens(service: subprocess.Popen, out: Path) -> dict[str, str]:
    """The tokens `grader run` prints once its API serves."""
    deadline = time.monotonic() + services.STARTUP_LIMIT_S
    while True:
        text = out.read_text(errors="replace")
        found = dict(re.findall(r"^(student|instructor) token: (\S+)$", text, re.M))
        if len(found) == 2 and "submitted " in text:
            return found
        if service.poll() is not None or time.monotonic() > deadline:
            raise RuntimeError(f"grader run did not start:\n{text[-3000:]}")
        time.sleep(0.2)
