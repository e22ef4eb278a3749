"""Sending work to Celery by task name (no task import, so the API never loads the tasks or case execution)."""

from __future__ import annotations


def send_case_run(case_run_id: int, attempt: int, backend: str) -> None:
    """Enqueue a case run on the queue of its requested backend: cpu, rocm or cuda, never another."""
    from worker.celery_app import BACKEND_QUEUES, RUN_TASK, app

    if backend not in BACKEND_QUEUES:
        raise ValueError(f"no queue for backend {backend!r}")
    app.send_task(RUN_TASK, args=[case_run_id, attempt], queue=backend)


def send_grade(submission_id: int) -> None:
    from worker.celery_app import GRADE_QUEUE, GRADE_TASK, app

    app.send_task(GRADE_TASK, args=[submission_id], queue=GRADE_QUEUE)


def resend(resend) -> None:
    """Enqueue what the reconciler marked (grader.reconcile.Resend)."""
    for case_run_id, attempt, backend in resend.case_runs:
        send_case_run(case_run_id, attempt, backend)
    for submission_id in resend.gradings:
        send_grade(submission_id)


EMBEDDED_QUEUES = ("cpu", "grade")  # what the embedded service's one worker consumes (grader.embedded)


def queue_listeners(queue: str, *, timeout_s: float = 1.0) -> list[str]:
    """Names of the Celery workers consuming `queue` now, asked over the broker (remote control, `timeout_s`).

    The embedded filesystem broker has no broadcast: there the answer is its one local worker's queues.
    """
    from worker.celery_app import app

    if str(app.conf.broker_url).startswith("filesystem"):
        return ["embedded worker"] if queue in EMBEDDED_QUEUES else []
    replies = app.control.inspect(timeout=timeout_s).active_queues() or {}
    return sorted(name for name, queues in replies.items() if any(q.get("name") == queue for q in queues))
