"""Every state machine and closed vocabulary of the service, as enums: the one place their values are written.

StrEnum members are their values (`SubmissionState.GRADED == "graded"`), so rows, JSON and templates hold plain
strings. The case spec's own vocabulary (backend, precision, execution mode) is declared by `rubric` as Literal types,
which a student's notebook reads without this package; the enums here are built from those Literals, so the lists
exist once.
"""

from __future__ import annotations

from enum import StrEnum
from typing import get_args

from rubric.results import Provenance
from rubric.specs import Backend as _BackendLiteral
from rubric.specs import Precision as _PrecisionLiteral


class SubmissionState(StrEnum):
    """running (case runs queued or running) -> grading (all finished, grade task sent) -> graded | failed."""

    RUNNING = "running"
    GRADING = "grading"
    GRADED = "graded"
    FAILED = "failed"


class CaseRunState(StrEnum):
    """queued -> running -> done | failed; requeue and resend go back to queued under a new delivery number."""

    QUEUED = "queued"
    RUNNING = "running"
    DONE = "done"
    FAILED = "failed"


TERMINAL = (CaseRunState.DONE, CaseRunState.FAILED)


class CaseRunPurpose(StrEnum):
    GRADING = "grading"  # one of a submission's cases: its grade waits for it
    AUDIT = "audit"  # an audit re-run on another backend, precision or mode: never holds a grade


class Role(StrEnum):
    STUDENT = "student"
    INSTRUCTOR = "instructor"
    AUDITOR = "auditor"


STAFF = (Role.INSTRUCTOR, Role.AUDITOR)

Backend = StrEnum("Backend", [(value.upper(), value) for value in get_args(_BackendLiteral)])
Backend.__doc__ = "Where a case runs, asked of Genesis exactly (never gs.gpu): one Celery queue each."
Precision = StrEnum("Precision", [(f"F{value}", value) for value in get_args(_PrecisionLiteral)])
Precision.__doc__ = "Floating-point bits of a case's simulation."
ExecutionMode = StrEnum("ExecutionMode", [(value.upper(), value) for value in
                                          get_args(Provenance.model_fields["execution_mode"].annotation)])
ExecutionMode.__doc__ = "A fresh isolated process per case (the lesson's contract) or a warm process per worker slot."


class Visibility(StrEnum):
    """When a student sees an item's score and feedback."""

    IMMEDIATE = "immediate"
    AFTER_DUE = "after_due"  # from the due date that applies to the student (their extension's where granted)
    ON_RELEASE = "on_release"  # once an instructor releases the assignment


class CountedAttempt(StrEnum):
    """Which of a student's graded attempts counts: the latest, or the best counted score (ties to the later)."""

    LATEST = "latest"
    BEST = "best"


class AssignmentParts(StrEnum):
    """The rubric items an assignment holds: checkpoint items, every other item, or the whole sheet."""

    CHECKPOINTS = "checkpoints"
    EXERCISES = "exercises"
    SHEET = "sheet"


class PoolState(StrEnum):
    """An assignment's variant pool (issue 34): measuring (some variant's runs or check outstanding) -> ready."""

    MEASURING = "measuring"
    READY = "ready"


class VariantState(StrEnum):
    """One drawn variant of a pool: drawn -> measuring -> kept | dropped (its check failed or was inconclusive, or its
    parameters break the space; the reason is stored and shown)."""

    DRAWN = "drawn"
    MEASURING = "measuring"
    KEPT = "kept"
    DROPPED = "dropped"


def values(enum: type[StrEnum]) -> list[str]:
    """The enum's values in declaration order (click choices, messages)."""
    return [member.value for member in enum]
