"""What the API accepts (…Create) and returns (…Public). Tables live in grader.core.models."""

from __future__ import annotations

from datetime import UTC, datetime
from typing import Annotated, Any, Literal

from pydantic import (AfterValidator, AwareDatetime, BaseModel, ConfigDict, Field, ValidationInfo, field_validator,
                      model_validator)
from pydantic_core import PydanticCustomError

from grader.core.states import AssignmentParts


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
        None, description="Staff only: run every case on this backend instead of the one each config names. Never "
                          "substituted; refused (409) when no worker listens on its queue.")
    force_rerun: bool = Field(False, description="Staff only: measure every case afresh instead of reusing stored "
                                                 "measurements.")
    assignment_id: int | None = Field(None, ge=1, le=2**31 - 1, description=(
        "Submit to this assignment of the caller's course: the sheet then answers exactly its items, and it is "
        "refused before it opens, after its hard close (or the student's extension) and beyond its attempt limit."))


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
    delivery: int = Field(description="Message number: each re-send makes every older message stale")
    tries: int | None = Field(description="Times a case process ran it (None where its measurements are withheld "
                                          "from the reader: 0 would say it reused a measurement)")
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
    report_complete: bool | None = Field(None, description=(
        "Once graded: false while the lab check of the stored grade is being evaluated (its scores are final "
        "already), true once it is stored with it; null before a grade"))
    total: float | None = None
    max_total: float | None = None
    assignment_id: int | None = None
    attempt: int | None = Field(None, description="Attempt number within its assignment (1, 2, ...)")
    late_seconds: int | None = Field(None, description="Seconds after the due date that applied (0: on time)")
    pending: str | None = Field(None, description=(
        "Which items' points are still withheld from this student and until when; `total` then counts the shown "
        "items only (null while every item is withheld)"))
    raw_score: float | None = Field(None, description="A graded attempt's score before the late penalty (null while "
                                                      "any of its items is withheld from the caller)")
    penalty: float | None = Field(None, description="Fraction of the raw score taken for lateness (a submission to "
                                                    "an assignment)")
    counted_score: float | None = Field(None, description="The raw score less the late penalty")
    counts: bool | None = Field(None, description=(
        "Whether this is the attempt that counts for its student (latest or best, as the assignment says)"))


class GradeItemPublic(BaseModel):
    model_config = ConfigDict(extra="allow")

    id: str
    question: str
    score: float | None = Field(description="None while the item is withheld from the caller (verdict pending)")
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
    pending: str | None = Field(None, description=(
        "Which items are withheld from this student and until when; `total` then counts the shown items only"))
    withheld_measurements: dict[str, str] = Field(default_factory=dict, description=(
        "{case run: why} of the runs whose measurements decide a withheld item: hidden until it is shown (their "
        "series, metrics, provenance, files, and the evidence of every item that reads them)"))
    check: dict[str, Any] | None = Field(None, description=(
        "The lab check the report page shows (verdict_line, the lesson's CHECK line, and each condition with its "
        "evidence): None until the report is complete, and while any item is withheld from the caller"))


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
    at: UtcDateTime | None = Field(description="When (None for a run whose measurements are withheld from the "
                                               "reader: its times would tell how long it ran and whether it reused)")


class Health(BaseModel):
    status: Literal["ok"]
    database: str
    version: str


def _naive_utc(value: datetime) -> datetime:
    """An instant with an offset, as the naive UTC the tables store; one that leaves the calendar is refused."""
    try:
        return value.astimezone(UTC).replace(tzinfo=None)
    except OverflowError:
        raise ValueError("outside the representable range of dates") from None


# An instant the API accepts: ISO 8601 with a UTC offset (a time without one is refused, never guessed).
UtcInput = Annotated[AwareDatetime, AfterValidator(_naive_utc)]


Visibility = Literal["immediate", "after_due", "on_release"]


class AssignmentCreate(Strict):
    """An assignment of one lesson in the instructor's course. Times are ISO 8601 with an offset."""

    title: str = Field(min_length=1, max_length=128)
    lesson: str = Field("L03", max_length=16, description="An installed lesson (`grader lesson list` names them)")
    part: AssignmentParts = Field(
        AssignmentParts.SHEET, description="The part of the sheet it holds. checkpoints: the lesson's concept checkpoints only (graded on the lesson's own cases, "
                             "at once where they are stored); exercises: every "
                             "other item (predictions, hands-on, extension); sheet: all items")
    open_at: UtcInput
    due_at: UtcInput
    hard_close_at: UtcInput = Field(description="No submission is accepted after it (extensions aside)")
    late_penalty_per_day: float = Field(0.0, ge=0.0, le=1.0, allow_inf_nan=False,
                                        description="Fraction of the raw score taken per day (or part) late")
    late_penalty_cap: float | None = Field(None, ge=0.0, le=1.0, allow_inf_nan=False,
                                           description="The most the late penalty may take, as a fraction")
    max_attempts: int | None = Field(None, ge=1, le=1000)
    max_per_hour: int | None = Field(None, ge=1, le=1000, description=(
        "Submissions one student may make in any 60 minutes; past it 429 with Retry-After"))
    counted_attempt: Literal["latest", "best"] = "latest"
    visibility: Visibility = Field("immediate", description=(
        "When students see scores and feedback: at once, from the due date that applies to them, or once released"))
    item_visibility: dict[Annotated[str, Field(max_length=16)], Visibility] = Field(
        default_factory=dict, max_length=64, description=(
            "Items shown otherwise than `visibility`, e.g. {\"C3\": \"on_release\"}; each must be one of the "
            "assignment's items"))

    @field_validator("lesson")
    @classmethod
    def _installed_lesson(cls, value: str) -> str:
        from rubric.lesson import lesson_names

        if value not in lesson_names():
            raise PydanticCustomError("lesson", "'{value}' is not an installed lesson (installed: {known})",
                                      {"value": value, "known": ", ".join(lesson_names())})
        return value

    @field_validator("due_at")
    @classmethod
    def _due_after_open(cls, value: datetime, info: ValidationInfo) -> datetime:
        if "open_at" in info.data and not info.data["open_at"] < value:
            raise PydanticCustomError("dates", "due_at must be after open_at")
        return value

    @field_validator("hard_close_at")
    @classmethod
    def _close_after_due(cls, value: datetime, info: ValidationInfo) -> datetime:
        if "due_at" in info.data and not info.data["due_at"] <= value:
            raise PydanticCustomError("dates", "hard_close_at must not be before due_at")
        return value


class ExtensionCreate(Strict):
    """One student's own due date and hard close for an assignment (replaces an earlier extension of theirs)."""

    student: str = Field(min_length=1, max_length=64)
    due_at: UtcInput
    hard_close_at: UtcInput

    @field_validator("hard_close_at")
    @classmethod
    def _close_after_due(cls, value: datetime, info: ValidationInfo) -> datetime:
        if "due_at" in info.data and not info.data["due_at"] <= value:
            raise PydanticCustomError("dates", "hard_close_at must not be before due_at")
        return value


class ExtensionPublic(BaseModel):
    assignment_id: int
    student: str
    due_at: UtcDateTime
    hard_close_at: UtcDateTime
    granted_by: str
    granted_at: UtcDateTime


class AssignmentPublic(BaseModel):
    model_config = ConfigDict(from_attributes=True)

    id: int
    course: str
    title: str
    lesson: str
    part: str
    item_ids: list[str] = Field(description="The rubric items the assignment grades")
    open_at: UtcDateTime
    due_at: UtcDateTime
    hard_close_at: UtcDateTime
    late_penalty_per_day: float
    late_penalty_cap: float | None
    max_attempts: int | None
    max_per_hour: int | None
    counted_attempt: str
    visibility: str
    item_visibility: dict[str, str] = Field(description="Items shown otherwise than `visibility`")
    released_at: UtcDateTime | None
    created_by: str
    created_at: UtcDateTime


class CountedGradePublic(BaseModel):
    """The attempt that counts for one student: its raw score, the late penalty taken and the counted score."""

    student: str
    submission_id: int
    attempt: int
    submitted_at: UtcDateTime
    late_seconds: int
    raw_score: float
    max_score: float
    penalty: float = Field(description="Fraction of the raw score taken for lateness (per day late, capped)")
    counted_score: float
    variant: str | None = Field(None, description="The student's lab variant (issue 34) the attempt was graded on; "
                                                  "null on an assignment without a variant pool")


class RosterImport(Strict):
    """A roster as CSV text with the header `student_id,name,email`, one student a row."""

    csv: str = Field(min_length=1, max_length=200_000)
    links: bool = Field(False, description="Also issue every student of the file a new sign-in link (single use, "
                                           "expiring; an earlier link of theirs stops working)")


class RosterEntry(BaseModel):
    student: str = Field(description="The student id: the name the service knows them by")
    name: str
    email: str
    created: bool = Field(description="False when the student was already on the roster (name and email updated)")
    token: str | None = Field(description="The new student's API token, shown this once; None on a re-import")
    sign_in_link: str | None = Field(None, description="With `links`: the student's new sign-in link, shown this once")
    sign_in_link_expires_at: datetime | None = None


class SignInLinkPublic(BaseModel):
    student: str
    sign_in_link: str = Field(description="The student's new sign-in link, shown this once: it works once, until "
                                          "expires_at; the earlier link no longer works")
    expires_at: datetime


class CoursePublic(BaseModel):
    name: str
    timezone: str = Field(description="IANA time zone the course's times are shown in (stored in UTC)")
    free_submissions: bool = Field(description=(
        "Whether students may submit outside an assignment (what an assignment withholds is withheld there too)"))
    created_at: UtcDateTime


class CourseUpdate(Strict):
    """Settings of a course an instructor may change: at least one; one left out is kept."""

    timezone: str | None = Field(None, min_length=1, max_length=64,
                                 description="An IANA time zone name, e.g. Europe/Berlin")
    free_submissions: bool | None = Field(None, description=(
        "Whether students may submit outside an assignment (staff always may)"))

    @model_validator(mode="after")
    def _some_setting(self) -> "CourseUpdate":
        if self.timezone is None and self.free_submissions is None:
            raise ValueError("name at least one setting: timezone, free_submissions")
        return self
