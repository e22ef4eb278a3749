"""Exceptions of case execution.

CaseExecutionError
 +-- ProvenanceError   the case did not run on the backend it asked for (or could not get it)
 +-- RenderError       rendering was requested and the camera failed; never a silent fallback to no frames

Also the exit statuses of a case process, shared by the process that sets them and the parent that reads them, and
the reason a case process stopped for its memory limit (a failure of the service's bound, not of the student's sheet).
"""

EXIT_OK, EXIT_ERROR, EXIT_PROVENANCE, EXIT_RENDER = 0, 1, 3, 4
# The words every reader matches (grader.ops' failure reasons, the report): never the words of a time-out or a crash.
MEMORY_LIMIT_EXCEEDED = "memory limit exceeded"


def memory_limit_error(limit_mb: int, resident_mb: int) -> str:
    """A case run's error when its case process passed the memory limit and was stopped."""
    return (f"{MEMORY_LIMIT_EXCEEDED}: {limit_mb} MB (the case process held {resident_mb} MB when it was stopped); "
            "a bound of the grading service (CASE_MEMORY_LIMIT_MB), not a fault of the sheet")


class CaseExecutionError(Exception):
    """Base of every case-execution failure."""


class ProvenanceError(CaseExecutionError):
    """Requested and actual backend differ, or the requested backend is unavailable."""


class RenderError(CaseExecutionError):
    """An enabled camera failed to produce a frame."""
