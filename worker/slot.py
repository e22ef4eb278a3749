"""The case-execution slot of one Celery worker process: its warm case process, started with the worker process
(warming up: settings.warm_up_backend) or on the first case, and kept.

The warm case process recycles itself after warm_max_cases or any failure; `close_slot` ends it when the worker
process shuts down.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from grader.core.settings import settings
from worker.case_process import WarmCaseProcess, run_case

_warm_process = None


def run_case_in_slot(spec, out_dir: Path, mode: str | None = None):
    """Run one case in this slot's warm case process, or isolated: `mode` when a run asks for one (an audit re-run),
    else the worker's setting. Always returns a CaseResult."""
    global _warm_process
    mode = mode or settings.execution_mode
    if mode == "warm" and _warm_process is None:
        _warm_process = _new_warm_process()
    return run_case(spec, out_dir, mode=mode, timeout_s=settings.case_time_limit_s,
                    memory_limit_mb=settings.case_memory_limit_mb,
                    warm_process=_warm_process if mode == "warm" else None)


def _new_warm_process():
    backend = None if settings.warm_up_backend == "off" else settings.warm_up_backend
    return WarmCaseProcess(max_cases=settings.warm_max_cases, reuse_scenes=settings.scene_reuse,
                           warm_up_backend=backend)


def start_slot(on_warm: Callable[[dict], None] | None = None) -> None:
    """Start this slot's warm case process with the worker process (settings.warm_up_backend), so that it imports
    Genesis and loads the lesson's kernels before the first case arrives. Returns at once: the process warms up on
    its own; `on_warm(line)` is called once it is warm (worker.warm_gate opens the worker's case queues when every
    slot is), at once when nothing is to warm up (isolated mode, warm-up off)."""
    global _warm_process
    if settings.execution_mode != "warm" or settings.warm_up_backend == "off":
        if on_warm is not None:
            on_warm({"warm_up_s": 0.0, "ok": True})
        return
    if _warm_process is None:
        _warm_process = _new_warm_process()
    _warm_process.start(on_warm)


def close_slot() -> None:
    global _warm_process
    if _warm_process is not None:
        _warm_process.close()
        _warm_process = None
