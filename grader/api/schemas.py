"""The API's own wire models: request and response bodies only the API's routes use (the models the services and the
API share are grader.core.schemas; a service's own results are typed beside it, in its context's package)."""

from __future__ import annotations

from datetime import datetime
from typing import Annotated, Any

from pydantic import BaseModel, ConfigDict, Field

from grader.core.schemas import UtcDateTime
from grader.services.rubrics.regrade import HASH_PATTERN, LESSON_PATTERN
from rubric.rubrics import VERSION_PATTERN

LESSON, VERSION = LESSON_PATTERN, VERSION_PATTERN


class TokensRevoked(BaseModel):
    student: str
    tokens_revoked: int
    sessions_revoked: int


class LtiRegistrationCreate(BaseModel):
    """A platform (an LMS) that may launch this tool into the course, with the values its set-up page shows."""

    issuer: str = Field(max_length=255, description="The platform's issuer (iss)")
    client_id: str = Field(max_length=255, description="The client id the platform gave this tool")
    deployment_ids: list[str] = Field(min_length=1, max_length=100, description="Deployment ids it launches from")
    auth_login_url: str = Field(max_length=2000, description="The platform's OIDC authorization endpoint")
    auth_token_url: str = Field(max_length=2000, description="The platform's OAuth2 token endpoint")
    key_set_url: str = Field(max_length=2000, description="The platform's JWKS URL")


class LtiRegistrationPublic(BaseModel):
    id: int
    course: str
    issuer: str
    client_id: str
    deployment_ids: list[str]
    auth_login_url: str
    auth_token_url: str
    key_set_url: str
    created_at: datetime


class ScoreSentPublic(BaseModel):
    student: str
    context: str = Field(description="The LMS course (launch context id)")
    status: str = Field(description="sent | unchanged | failed | withheld (an item is still withheld from the student)")
    score: float | None
    error: str | None


class RosterSyncPublic(BaseModel):
    added: list[str]
    updated: list[str]
    dropped: list[str] = Field(description="No longer active in the LMS: kept here with their submissions")
    unchanged: int


class RubricVersionPublic(BaseModel):
    lesson: str
    version: str
    content_hash: str
    source: str
    published_by: str | None
    published_at: UtcDateTime
    review: dict[str, Any]


class RegradeRequest(BaseModel):
    model_config = ConfigDict(extra="forbid")

    lesson: Annotated[str, Field(pattern=LESSON)] = "L03"
    version: Annotated[str, Field(pattern=VERSION, max_length=32)]
    # The preview's content_hash: the commit is refused (409) if the version's content is not what was previewed.
    content_hash: Annotated[str, Field(pattern=HASH_PATTERN)]


class AuditEntryPublic(BaseModel):
    model_config = ConfigDict(from_attributes=True)

    id: int
    created_at: UtcDateTime
    lesson: str
    case: str
    spec_key: str
    spec: dict[str, Any]
    left_case_run_id: int
    right_case_run_id: int | None
    left_variant: str
    right_variant: str
    left_provenance: dict[str, Any] | None
    right_provenance: dict[str, Any] | None
    classification: str
    summary: str
    comparison: dict[str, Any] | None
    figures: list[str]
    requested_by_id: int | None


class VariantPoolCreate(BaseModel):
    """A variant pool to draw for an assignment before it opens (issue 34)."""

    seed: int = Field(ge=0, le=2**31 - 1, description="The draw's seed: the same seed draws the same pool")
    k: int = Field(default=16, ge=1, le=64, description="How many variants to keep: the pool draws and measures until "
                  "K pass the lesson's lab check or its draw budget is spent (issue 47)")
    budget: int | None = Field(default=None, ge=1, le=256, description="The most variants the pool may draw and measure "
                               "to keep K (K to 4 x K; default 2 x K)")
    minimum: int | None = Field(default=None, ge=1, le=64, description="How many must be kept before students get one "
                                "(1 to K); default: once the pool is ready")
    space_version: str | None = Field(default=None, max_length=32, pattern=r"^[0-9]+(\.[0-9]+)*$",
                                      description="The variant space version to draw from (one reviewed for the "
                                      "course's rubric version); default: the latest")


class VariantPoolTopUp(BaseModel):
    """Variants to add to a pool at any time (issue 47); none: draw the K - kept a ready pool lacks."""

    more: int | None = Field(default=None, ge=1, le=64, description="How many more variants to keep")


class RosterStudentPublic(BaseModel):
    """A student of the course as the roster holds them (never a token or a sign-in link)."""

    student: str = Field(description="The student id (their name in the service)")
    name: str | None
    email: str | None


class CourseChangePublic(BaseModel):
    """One change to the course's set-up, with who made it and when; `detail` holds the values before and after."""

    id: int
    at: UtcDateTime
    by: str
    kind: str = Field(description="course_settings, assignment_created, assignment_edited, released, "
                                  "extension_granted, extension_revoked, roster_imported or sign_in_link_issued")
    assignment_id: int | None
    summary: str
    detail: dict[str, Any]
