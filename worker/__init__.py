"""Case execution: the Genesis case processes (isolated and warm), the Celery app and its tasks.

The parent-side API here never imports Genesis; only worker.engine does, inside a case process.
"""

from .case_process import WarmCaseProcess, load_result, run_case, run_cases
from .errors import CaseExecutionError, ProvenanceError, RenderError

__all__ = ["CaseExecutionError", "ProvenanceError", "RenderError", "WarmCaseProcess", "load_result", "run_case",
           "run_cases"]
