"""What the API accepts (…Create) and returns (…Public). Tables live in grader.models."""

from __future__ import annotations

from datetime import UTC, datetime
from typing import Annotated, Any, Literal

from pydantic import AfterValidator, BaseModel, ConfigDict, Field


def as_utc(value: datetime) -> datetime:
    """The database stores naive UTC; every timestamp leaves the API as UTC with an explicit offset (RFC 3339)."""
    return value.replace(tzinfo=UTC) if value.tzinfo is None else value.astimezone(UTC)


UtcDateTime = Annotated[datetime, AfterValidator(as_utc)]


class Strict(BaseModel):
    model_config = ConfigDict(extra="forbid")


class SubmissionCreate(Strict):
    """A prediction sheet (its modified case configs inside) to grade on measured results."""

    sheet: dict[str, Any] = Field(description="The lesson's prediction sheet, including the student's case configs.")
    backend: Literal["cpu", "rocm", "cuda"] | None = Field(
        None, description="Run every case on this backend instead of the one each config names. Never substituted.")
    force_rerun: bool = Field(False, description="Measure every case afresh instead of reusing stored measurements.")


class FieldError(BaseModel):
    field: str = Field(description="Dotted path of the offending item in the body, e.g. sheet.answers.A3.agree; "
                                   "path.NAME or query.NAME for a parameter; body for the body as a whole")
    rule: str = Field(description="The rule it breaks")


class ErrorBody(BaseModel):
    """Every error the API returns has this shape."""

    detail: str
    errors: list[FieldError] = []


class Progress(BaseModel):
    total: int
    queued: int
    running: int
    done: int
    failed: int


class CaseRunPublic(BaseModel):
    """One case run: state, what was asked, what ran, and where the numbers came from."""

    model_config = ConfigDict(from_attributes=True)

    id: int
    name: str
    kind: str
    backend: str = Field(description="Requested backend (the queue it was sent to)")
    actual_backend: str | None = Field(description="Backend that produced the numbers, from provenance")
    precision: str
    status: str
    result_status: str | None
    attempt: int
    tries: int
    content_key: str | None
    reused_from_id: int | None = Field(description="The case run whose measurement this one reused, if any")
    measurement_id: int | None
    error: str | None
    wall_s: float | None
    spec: dict[str, Any]
    provenance: dict[str, Any] | None
    metrics: dict[str, Any] | None = Field(description="Metrics computed once where the case ran (rubric.metrics)")
    queued_at: UtcDateTime
    started_at: UtcDateTime | None
    finished_at: UtcDateTime | None
    purpose: str = Field("grading", description="grading, or audit: a re-measurement that never counts in a grade")
    mode: str | None = Field(None, description="Execution mode the run asked for (None: the worker's setting)")
    source_case_run_id: int | None = Field(None, description="The case run an audit re-run re-measures")

    @property
    def reused(self) -> bool:
        return self.reused_from_id is not None


class SubmissionPublic(BaseModel):
    model_config = ConfigDict(from_attributes=True)

    id: int
    lesson: str
    student: str
    status: Literal["running", "grading", "graded", "failed"]
    force_rerun: bool
    error: str | None
    progress: Progress
    created_at: UtcDateTime
    updated_at: UtcDateTime
    graded_at: UtcDateTime | None
    total: float | None = None
    max_total: float | None = None


class GradeItemPublic(BaseModel):
    model_config = ConfigDict(extra="allow")

    id: str
    question: str
    score: float
    max_score: float
    verdict: str
    feedback: str
    evidence: Any = None


class GradePublic(BaseModel):
    submission_id: int
    total: float
    max_total: float
    rubric_lesson: str
    rubric_version: str
    rubric_hash: str
    items: list[GradeItemPublic]
    created_at: UtcDateTime
    superseded_at: UtcDateTime | None = None  # set once a committed regrade replaced this grade
    regrade_id: int | None = None  # the regrade that wrote this grade; None for the first grading


class GradeHistoryEntry(BaseModel):
    """One grade a submission had: which rubric version, the total, when, and whether a regrade replaced it."""

    rubric_version: str
    rubric_hash: str
    total: float
    max_total: float
    created_at: UtcDateTime
    superseded_at: UtcDateTime | None
    regrade_id: int | None
    regraded_by: str | None
    current: bool


class EventPublic(BaseModel):
    model_config = ConfigDict(from_attributes=True)

    case_run_id: int | None
    state: str
    detail: str | None
    at: UtcDateTime


class Health(BaseModel):
    status: Literal["ok"]
    database: str
    version: str
