"""Sending work to Celery by task name (no task import, so the API never loads the tasks or case execution)."""

from __future__ import annotations

from grader.core import warmth
from grader.core.lifecycle import NEW_PRIORITY, POOL_PRIORITY, REQUEUED_PRIORITY, RERUN_PRIORITY


def send_case_run(case_run_id: int, delivery: int, backend: str, *, priority: int = NEW_PRIORITY) -> None:
    """Enqueue a case run on the queue of its requested backend: cpu, rocm or cuda, never another."""
    # lazy: grader.main must not load Celery (test_the_api_never_imports_genesis_or_torch)
    from worker.celery_app import BACKEND_QUEUES, RUN_TASK, app

    if backend not in BACKEND_QUEUES:
        raise ValueError(f"no queue for backend {backend!r}")
    app.send_task(RUN_TASK, args=[case_run_id, delivery], queue=backend, priority=priority)


def send_grade(submission_id: int) -> None:
    # lazy: grader.main must not load Celery (test_the_api_never_imports_genesis_or_torch)
    from worker.celery_app import GRADE_QUEUE, GRADE_TASK, app

    app.send_task(GRADE_TASK, args=[submission_id], queue=GRADE_QUEUE)


def resend(resend) -> None:
    """Enqueue what the reconciler marked (grader.reconcile.Resend): a variant pool's runs behind every student's
    again (POOL_PRIORITY), whether they waited past the queue lease behind them or their worker died."""
    for case_run_id, delivery, backend in resend.case_runs:
        rerun = case_run_id in resend.were_running
        priority = (POOL_PRIORITY if case_run_id in resend.pool_runs
                    else RERUN_PRIORITY if rerun else REQUEUED_PRIORITY)
        send_case_run(case_run_id, delivery, backend, priority=priority)
    for submission_id in resend.gradings:
        send_grade(submission_id)


EMBEDDED_QUEUES = ("cpu", "grade")  # what the embedded service's one worker consumes (grader.embedded)


def queue_listeners(queue: str, *, timeout_s: float = 1.0) -> list[str]:
    """Names of the Celery workers consuming `queue` now, asked over the broker (remote control, `timeout_s`).

    The embedded filesystem broker has no broadcast: there the answer is its one local worker's queues. A worker
    warming up (grader.core.warmth) listens too: it consumes its case queues once warm.
    """
    workers = live_workers(timeout_s=timeout_s)
    if workers is None:
        return ["embedded worker"] if queue in EMBEDDED_QUEUES else []
    listening = {name for name, queues in workers.items() if queue in queues}
    try:  # a worker warming up holds its case queues back (worker.warm_gate), yet a run sent there is for it
        listening |= {w.name for w in warmth.live() or [] if queue in w.queues}
    except Exception:  # noqa: BLE001 - what remote control answered stands
        pass
    return sorted(listening)


def queue_depths() -> dict[str, int | None]:
    """Messages waiting in each queue, asked of the broker (None for a queue the broker could not answer for)."""
    # lazy: kombu is Celery's transport, loaded with it only when the broker is asked (never at API start)
    from kombu.exceptions import ChannelError

    # lazy: grader.main must not load Celery (test_the_api_never_imports_genesis_or_torch)
    from worker.celery_app import BACKEND_QUEUES, GRADE_QUEUE, app

    depths: dict[str, int | None] = {}
    with app.connection_for_read() as connection:
        channel = connection.default_channel
        for queue in (*BACKEND_QUEUES, GRADE_QUEUE):
            try:
                depths[queue] = channel.queue_declare(queue=queue, passive=True).message_count
            except ChannelError:  # a virtual transport's queue with no message has no key yet
                depths[queue] = 0
            except Exception:  # noqa: BLE001 - an unreachable broker shows as unknown, never as an empty queue
                depths[queue] = None
    return depths


def live_workers(*, timeout_s: float = 1.0) -> dict[str, list[str]] | None:
    """Each answering worker's queues (remote control); None where the broker has no broadcast (embedded)."""
    # lazy: grader.main must not load Celery (test_the_api_never_imports_genesis_or_torch)
    from worker.celery_app import app

    if str(app.conf.broker_url).startswith("filesystem"):
        return None
    replies = app.control.inspect(timeout=timeout_s).active_queues() or {}
    return {name: sorted(q.get("name", "?") for q in queues) for name, queues in sorted(replies.items())}


MARKER_QUEUE = "broker-marker"  # no worker consumes it: a message left there stays until the broker loses it


def broker_kept_marker() -> bool | None:
    """Whether the marker message left on MARKER_QUEUE is still on the broker: True; False when it is gone (a
    restart without persistence lost every message since it was left; it is left again now); None when the broker
    cannot be asked. A broker emptied under load is noticed this way at once, even while new runs fill its queues.
    """
    # lazy: kombu is Celery's transport, loaded with it only when the broker is asked (never at API start)
    from kombu.exceptions import ChannelError

    try:
        # lazy: grader.main must not load Celery (test_the_api_never_imports_genesis_or_torch)
        from worker.celery_app import app

        with app.connection_for_write() as connection:
            marker = connection.SimpleQueue(MARKER_QUEUE)
            try:
                try:
                    kept = marker.qsize() > 0
                except ChannelError:  # a virtual transport's queue with no message has no key
                    kept = False
                if not kept:
                    marker.put({"left_by": "grader reconcile"})
                return kept
            finally:
                marker.close()
    except Exception:  # noqa: BLE001 - an unreachable broker says nothing about its messages
        return None


def grade_held(submission_id: int) -> tuple[str, int]:
    """How `held_tasks` names a grade task for `submission_id` among a worker's held tasks."""
    return ("grade", submission_id)


def held_tasks(*, timeout_s: float = 2.0) -> tuple[dict[str, set[tuple]], dict[str, int]] | None:
    """Liveness as the broker sees it: per answering worker, the (case_run_id, delivery) of the case runs it is
    running or holds prefetched, and `grade_held(submission_id)` for each grade task it holds; and the messages
    waiting per queue. None when not knowable (embedded broker, or the broker unreachable): the reconciler then falls
    back to leases."""
    # lazy: grader.main must not load Celery (test_the_api_never_imports_genesis_or_torch)
    from worker.celery_app import GRADE_TASK, RUN_TASK, app

    if str(app.conf.broker_url).startswith("filesystem"):
        return None
    try:
        inspect = app.control.inspect(timeout=timeout_s)
        active, reserved = inspect.active(), inspect.reserved()
        depths = queue_depths()
    except Exception:  # noqa: BLE001 - no broker, no liveness: leases decide
        return None
    if active is None or any(d is None for d in depths.values()):
        return None
    held: dict[str, set[tuple[int, int]]] = {}
    for replies in (active, reserved or {}):
        for worker, tasks in replies.items():
            mine = held.setdefault(worker, set())
            for task in tasks:
                args = task.get("args") or []
                if task.get("name") == RUN_TASK and len(args) == 2:
                    mine.add((int(args[0]), int(args[1])))
                elif task.get("name") == GRADE_TASK and len(args) == 1:
                    mine.add(grade_held(int(args[0])))
    return held, depths
