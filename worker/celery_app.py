"""The Celery app: one queue per backend (cpu, rocm, cuda) plus `grade`; reliability options in one place.

Worker commands (one per queue; concurrency 1 because each slot holds a ~0.8 GB warm Genesis process):
  cpu   celery -A worker.celery_app worker -Q cpu,grade -c 1 -n cpu@%h
  rocm  celery -A worker.celery_app worker -Q rocm -c 1 -n rocm@%h     (ROCm torch image, /dev/kfd, /dev/dri)
  cuda  celery -A worker.celery_app worker -Q cuda -c 1 -n cuda@%h
Or `grader worker --queue cpu` which runs the same thing.
"""

from __future__ import annotations

from celery import Celery
from kombu import Queue

from grader.settings import settings

BACKEND_QUEUES = ("cpu", "rocm", "cuda")
GRADE_QUEUE = "grade"
RUN_TASK = "worker.tasks.run_case_run"
GRADE_TASK = "worker.tasks.grade_submission"

app = Celery("grader", broker=settings.broker_url, include=["worker.tasks"])
app.conf.update(
    task_queues=[Queue(name) for name in (*BACKEND_QUEUES, GRADE_QUEUE)],
    # A case run's queue is its requested backend, given explicitly at send time; grading has its own queue.
    task_routes={GRADE_TASK: {"queue": GRADE_QUEUE}},
    task_default_queue="cpu",
    task_create_missing_queues=False,
    # Ack only after the task finished; a worker process lost mid-case puts the message back.
    task_acks_late=True,
    task_reject_on_worker_lost=True,
    worker_prefetch_multiplier=1,
    task_ignore_result=True,
    # The runner stops a case at case_time_limit_s and returns a timeout result; these only catch a hung task.
    task_soft_time_limit=settings.case_time_limit_s + 60,
    task_time_limit=settings.case_time_limit_s + 120,
    task_serializer="json",
    accept_content=["json"],
    broker_connection_retry_on_startup=True,
    # Redis: an unacked message returns after this; the reconciler usually re-sends sooner.
    broker_transport_options={"visibility_timeout": int(settings.lease_s) + 60, "polling_interval": 0.5},
    worker_hijack_root_logger=False,
)
