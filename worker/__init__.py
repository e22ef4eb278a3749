"""Case execution: the Genesis runner (isolated and warm case processes) and, later, the Celery tasks.

The parent-side API here never imports Genesis; only worker.engine does, inside a case process.
"""

from .errors import ProvenanceError, RenderError, RunnerError
from .runner import WarmExecutor, load_result, run_case, run_cases

__all__ = ["ProvenanceError", "RenderError", "RunnerError", "WarmExecutor", "load_result", "run_case", "run_cases"]
