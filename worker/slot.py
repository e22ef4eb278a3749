"""The case-execution slot of one Celery worker process: its warm case process, made on the first case and kept.

The warm case process recycles itself after warm_max_cases or any failure; `close_slot` ends it when the worker
process shuts down.
"""

from __future__ import annotations

from pathlib import Path

from grader.settings import settings

_warm_process = None


def run_case_in_slot(spec, out_dir: Path, mode: str | None = None):
    """Run one case in this slot's warm case process, or isolated: `mode` when a run asks for one (an audit re-run),
    else the worker's setting. Always returns a CaseResult."""
    global _warm_process
    from worker.case_process import WarmCaseProcess, run_case

    mode = mode or settings.execution_mode
    if mode == "warm" and _warm_process is None:
        _warm_process = WarmCaseProcess(max_cases=settings.warm_max_cases, reuse_scenes=settings.scene_reuse)
    return run_case(spec, out_dir, mode=mode, timeout_s=settings.case_time_limit_s,
                    warm_process=_warm_process if mode == "warm" else None)


def close_slot() -> None:
    global _warm_process
    if _warm_process is not None:
        _warm_process.close()
        _warm_process = None
