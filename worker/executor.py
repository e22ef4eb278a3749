"""The warm executor held by one worker process: created on its first case, recycled by the runner on any error."""

from __future__ import annotations

from pathlib import Path

from grader.settings import settings

_executor = None


def run(spec, out_dir: Path):
    """Run one case in this process's warm executor (or isolated, per settings); always returns a CaseResult."""
    global _executor
    from worker.runner import WarmExecutor, run_case

    if settings.execution_mode == "warm" and _executor is None:
        _executor = WarmExecutor(max_cases=settings.warm_max_cases)
    return run_case(spec, out_dir, mode=settings.execution_mode, timeout_s=settings.case_time_limit_s,
                    executor=_executor)


def close() -> None:
    global _executor
    if _executor is not None:
        _executor.close()
        _executor = None
