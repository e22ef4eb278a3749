"""The Celery app: one queue per backend (cpu, rocm, cuda) plus `grade`; reliability options in one place.

A grade's lab check (`complete_grade`, evaluated after the grade is stored) goes on the cpu queue at the lowest
priority (grader.core.lifecycle.COMPLETE_PRIORITY): a CPU worker evaluates it when no case waits, so under a
deadline's load the cases and grades of every submission come before any lab check.

Worker commands (one per queue), built by `worker_argv` for `grader worker` and the embedded service. Each worker has
`worker_concurrency` case slots (prefork processes), each holding its own ~0.8 GB warm Genesis process: one per core
by default, as many as memory holds at the case memory limit; a case steps on one thread, so a submission's runs on
two slots take about the time of the longer one (docs/benchmark.md). A worker consumes its case queues only once
every slot is warm (worker.warm_gate):
  cpu   grader worker --queue cpu --queue grade
  rocm  grader worker --queue rocm     (ROCm torch image, /dev/kfd, /dev/dri)
  cuda  grader worker --queue cuda

Embedded broker (no server): kombu's filesystem transport under DATA_DIR/broker. Measured on the 2-core dev machine
(20 no-op tasks, one solo worker): filesystem median 0.21 s / max 0.42 s from send to start; the SQLAlchemy
transport on SQLite median 0.64 s / max 1.87 s (it polls once a second and takes no polling option). A worker with
prefetch 1 fetches its next task only at the next poll, so each task costs up to one polling interval: at 0.2 s a
fully reused submission (10 tasks) spent ~2 s waiting on polls, so the filesystem broker polls every 0.05 s (a
listdir of a small folder; `python -m tools.bench --only submission` shows the effect). Both restore
a rejected message (worker process lost) and lose unacked messages only if the whole worker dies, which the
reconciler covers. Deployment uses Redis (BROKER_URL=redis://...).
"""

from __future__ import annotations

import os
import sys
from collections.abc import Sequence

from celery import Celery
from kombu import Queue
from kombu.transport import TRANSPORT_ALIASES

from grader.core.states import Backend, values
from grader.core.settings import settings
from worker.warm_gate import WarmGate

# filesystem:// is kombu's filesystem transport serving messages by priority (worker.filesystem_broker), in every
# process that sends or consumes: a re-sent run goes ahead of the queue as it does on Redis.
TRANSPORT_ALIASES["filesystem"] = "worker.filesystem_broker:Transport"


BROKER_POLL_S = 0.05


def transport_options(url: str) -> dict:
    """Per-transport options: kombu passes SQLAlchemy-transport options to create_engine, so none go there."""
    if url.startswith("redis"):
        # An unacked message returns after this; the reconciler usually re-sends sooner.
        # One list per priority 0-9 (kombu's default is 0, 3, 6, 9, which would merge a student's fair priorities,
        # grader.core.lifecycle.FAIR_PRIORITIES, into one first-come-first-served list).
        return {"visibility_timeout": int(settings.lease_s) + 60, "priority_steps": list(range(10))}
    if url.startswith("filesystem"):
        folder = settings.data_dir.absolute() / "broker"
        (folder / "processed").mkdir(parents=True, exist_ok=True)
        # control_folder defaults to ./control, relative to whatever directory a process started in.
        return {"data_folder_in": str(folder), "data_folder_out": str(folder), "store_processed": False,
                "processed_folder": str(folder / "processed"), "control_folder": str(folder / "control"),
                "polling_interval": BROKER_POLL_S}
    return {}


BACKEND_QUEUES = tuple(values(Backend))  # one queue per backend, never another
GRADE_QUEUE = "grade"
RUN_TASK = "worker.tasks.run_case_run"
GRADE_TASK = "worker.tasks.grade_submission"
COMPLETE_TASK = "worker.tasks.complete_grade"
COMPLETE_QUEUE = "cpu"  # a grade's lab check is CPU work, behind the waiting case runs (see the module's docstring)

def worker_concurrency() -> int:
    """Case slots per worker: settings.worker_concurrency, or (0) one per core this process may run on (its CPU
    affinity: a container's cpuset), no more than the host's memory holds with every slot at case_memory_limit_mb."""
    if settings.worker_concurrency:
        return settings.worker_concurrency
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    if settings.case_memory_limit_mb and hasattr(os, "sysconf"):
        memory_mb = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES") // 2**20
        return max(1, min(cores, memory_mb // settings.case_memory_limit_mb))
    return max(1, cores)


app = Celery("grader", broker=settings.broker_url, include=["worker.tasks"])
app.conf.update(
    task_queues=[Queue(name) for name in (*BACKEND_QUEUES, GRADE_QUEUE)],
    # A case run's queue is its requested backend, given explicitly at send time; grading has its own queue.
    task_routes={GRADE_TASK: {"queue": GRADE_QUEUE}, COMPLETE_TASK: {"queue": COMPLETE_QUEUE}},
    task_default_queue="cpu",
    task_create_missing_queues=False,
    # Ack only after the task finished; a worker process lost mid-case puts the message back.
    task_acks_late=True,
    task_reject_on_worker_lost=True,
    worker_prefetch_multiplier=1,
    worker_concurrency=worker_concurrency(),
    # A pool process blocks in nothing at its start (its slot warms up on threads of its own), yet on a loaded host
    # its init may take longer than Celery's 4 s; a pool process given up on is a slot lost and replaced again.
    worker_proc_alive_timeout=60,
    task_ignore_result=True,
    # worker.case_process stops a case at case_time_limit_s and returns a timeout result; these only catch a hung task.
    task_soft_time_limit=settings.case_time_limit_s + 60,
    task_time_limit=settings.case_time_limit_s + 120,
    task_serializer="json",
    accept_content=["json"],
    broker_connection_retry_on_startup=True,
    broker_transport_options=transport_options(settings.broker_url),
    worker_hijack_root_logger=False,
)
app.steps["consumer"].add(WarmGate)  # case queues consumed only once every slot is warm


def worker_argv(queues: Sequence[str], *, name: str, loglevel: str = "info", heartbeat: bool = True) -> list[str]:
    """The command line of one Celery worker on `queues`: prefork, no gossip or mingle; its slots are
    worker_concurrency() as the worker's own environment sets it (WORKER_CONCURRENCY), read where it starts.

    heartbeat=False also drops worker heartbeats (the embedded service, one worker on a filesystem broker).
    """
    argv = [sys.executable, "-m", "celery", "-A", "worker.celery_app", "worker", "-Q", ",".join(queues),
            "--pool", "prefork", "-n", name, "--loglevel", loglevel, "--without-gossip", "--without-mingle"]
    return argv if heartbeat else [*argv, "--without-heartbeat"]
