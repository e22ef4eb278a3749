"""Exceptions of case execution.

CaseExecutionError
 +-- ProvenanceError   the case did not run on the backend it asked for (or could not get it)
 +-- RenderError       rendering was requested and the camera failed; never a silent fallback to no frames

Also the exit statuses of a case process, shared by the process that sets them and the parent that reads them.
"""

EXIT_OK, EXIT_ERROR, EXIT_PROVENANCE, EXIT_RENDER = 0, 1, 3, 4


class CaseExecutionError(Exception):
    """Base of every case-execution failure."""


class ProvenanceError(CaseExecutionError):
    """Requested and actual backend differ, or the requested backend is unavailable."""


class RenderError(CaseExecutionError):
    """An enabled camera failed to produce a frame."""
