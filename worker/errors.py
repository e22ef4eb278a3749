"""Exceptions of case execution.

RunnerError
 +-- ProvenanceError   the case did not run on the backend it asked for (or could not get it)
 +-- RenderError       rendering was requested and the camera failed; never a silent fallback to no frames
"""


class RunnerError(Exception):
    """Base of every case-execution failure."""


class ProvenanceError(RunnerError):
    """Requested and actual backend differ, or the requested backend is unavailable."""


class RenderError(RunnerError):
    """An enabled camera failed to produce a frame."""
