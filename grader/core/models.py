"""Database tables (SQLAlchemy 2): courses, users and tokens, assignments and extensions, submissions, case runs,
measurements, rubric versions, grades with their history, regrades, events, variant pools.

All timestamps are naive UTC. Every state change of a submission or case run also appends an Event row.
"""

from __future__ import annotations

from datetime import datetime
from typing import Any

from sqlalchemy import (JSON, Boolean, DateTime, Float, ForeignKey, Index, Integer, LargeBinary, String, Text,
                        UniqueConstraint, text)
from sqlalchemy.orm import DeclarativeBase, Mapped, mapped_column, relationship

from grader.core import clock
from grader.core.states import CaseRunPurpose, CaseRunState, SubmissionState

# The values of role, status, purpose, part, counted_attempt and visibility columns are grader.core.states' enums.


def utcnow() -> datetime:
    """Naive UTC now from the service's one clock (grader.core.clock), which tests may freeze or shift."""
    return clock.now()


class Base(DeclarativeBase):
    type_annotation_map = {dict[str, Any]: JSON, list[Any]: JSON}


class Course(Base):
    __tablename__ = "courses"

    id: Mapped[int] = mapped_column(primary_key=True)
    name: Mapped[str] = mapped_column(String(64), unique=True)
    created_at: Mapped[datetime] = mapped_column(DateTime, default=utcnow)
    # The IANA zone the course's times are shown in (pages, refusal messages); they are stored in UTC regardless.
    timezone: Mapped[str] = mapped_column(String(64), default="UTC", server_default="UTC")
    # Whether students may submit outside an assignment; what an assignment withholds is withheld there too.
    free_submissions: Mapped[bool] = mapped_column(Boolean, default=True, server_default=text("true"))


class User(Base):
    __tablename__ = "users"
    __table_args__ = (UniqueConstraint("course_id", "name"),)

    id: Mapped[int] = mapped_column(primary_key=True)
    course_id: Mapped[int] = mapped_column(ForeignKey("courses.id"), index=True)
    name: Mapped[str] = mapped_column(String(64))
    role: Mapped[str] = mapped_column(String(16))
    created_at: Mapped[datetime] = mapped_column(DateTime, default=utcnow)
    # From a roster import (`name` is then the student id): the person's full name and email.
    full_name: Mapped[str | None] = mapped_column(String(128))
    email: Mapped[str | None] = mapped_column(String(254))

    course: Mapped[Course] = relationship(lazy="joined")


class ApiToken(Base):
    """Only the sha256 of a token is stored; the token itself is shown once, when it is created."""

    __tablename__ = "api_tokens"

    id: Mapped[int] = mapped_column(primary_key=True)
    user_id: Mapped[int] = mapped_column(ForeignKey("users.id"), index=True)
    token_hash: Mapped[str] = mapped_column(String(64), unique=True)
    created_at: Mapped[datetime] = mapped_column(DateTime, default=utcnow)
    # None: never expires (only a token made before expiry existed and the migration did not reach).
    expires_at: Mapped[datetime | None] = mapped_column(DateTime)
    revoked_at: Mapped[datetime | None] = mapped_column(DateTime)

    user: Mapped[User] = relationship(lazy="joined")


class WebSession(Base):
    """A page sign-in: the browser's cookie holds a random secret, this row only its sha256. It ends when idle past
    settings.session_idle_s, at expires_at, or when revoked (sign-out, its token revoked, an instructor's revoke)."""

    __tablename__ = "web_sessions"

    id: Mapped[int] = mapped_column(primary_key=True)
    user_id: Mapped[int] = mapped_column(ForeignKey("users.id"), index=True)
    # The token signed in with: revoking it ends the sessions it opened.
    token_id: Mapped[int | None] = mapped_column(ForeignKey("api_tokens.id"), index=True)
    secret_hash: Mapped[str] = mapped_column(String(64), unique=True)
    created_at: Mapped[datetime] = mapped_column(DateTime, default=utcnow)
    last_seen_at: Mapped[datetime] = mapped_column(DateTime, default=utcnow)
    expires_at: Mapped[datetime] = mapped_column(DateTime)
    revoked_at: Mapped[datetime | None] = mapped_column(DateTime)

    user: Mapped[User] = relationship(lazy="joined")


class SignInLink(Base):
    """A student's single-use sign-in link (`/sign-in/link/SECRET`): only the sha256 of its random secret is stored.
    Using it opens a page session; it is refused once used, expired, or revoked (by a re-issue)."""

    __tablename__ = "sign_in_links"

    id: Mapped[int] = mapped_column(primary_key=True)
    user_id: Mapped[int] = mapped_column(ForeignKey("users.id"), index=True)
    secret_hash: Mapped[str] = mapped_column(String(64), unique=True)
    created_at: Mapped[datetime] = mapped_column(DateTime, default=utcnow)
    expires_at: Mapped[datetime] = mapped_column(DateTime)
    used_at: Mapped[datetime | None] = mapped_column(DateTime)
    revoked_at: Mapped[datetime | None] = mapped_column(DateTime)

    user: Mapped[User] = relationship(lazy="joined")


class Assignment(Base):
    """What a course asks of its students for one lesson: which items, when, how late work and attempts count.

    `items`: checkpoints (the rubric items of part "checkpoint"), exercises (every other item) or sheet (all).
    """

    __tablename__ = "assignments"

    id: Mapped[int] = mapped_column(primary_key=True)
    course_id: Mapped[int] = mapped_column(ForeignKey("courses.id"), index=True)
    title: Mapped[str] = mapped_column(String(128))
    lesson: Mapped[str] = mapped_column(String(16))
    part: Mapped[str] = mapped_column(String(16))
    open_at: Mapped[datetime] = mapped_column(DateTime)
    due_at: Mapped[datetime] = mapped_column(DateTime)
    hard_close_at: Mapped[datetime] = mapped_column(DateTime)
    late_penalty_per_day: Mapped[float] = mapped_column(Float, default=0.0)  # fraction of the raw score per day
    late_penalty_cap: Mapped[float | None] = mapped_column(Float)  # the most the penalty may take, as a fraction
    max_attempts: Mapped[int | None] = mapped_column(Integer)
    max_per_hour: Mapped[int | None] = mapped_column(Integer)  # submissions per student in any 60 minutes
    counted_attempt: Mapped[str] = mapped_column(String(8))  # latest | best
    visibility: Mapped[str] = mapped_column(String(16))  # immediate | after_due | on_release
    # Items shown otherwise than `visibility`: {item id: immediate | after_due | on_release}.
    item_visibility: Mapped[dict[str, Any]] = mapped_column(JSON, default=dict, server_default="{}")
    released_at: Mapped[datetime | None] = mapped_column(DateTime)
    created_by_id: Mapped[int] = mapped_column(ForeignKey("users.id"))
    created_at: Mapped[datetime] = mapped_column(DateTime, default=utcnow)

    course: Mapped[Course] = relationship(lazy="joined")
    created_by: Mapped[User] = relationship(lazy="joined")


class Extension(Base):
    """One student's own dates for one assignment, with who granted them; the latest grant replaces the earlier."""

    __tablename__ = "extensions"
    __table_args__ = (UniqueConstraint("assignment_id", "student_id"),)

    id: Mapped[int] = mapped_column(primary_key=True)
    assignment_id: Mapped[int] = mapped_column(ForeignKey("assignments.id"), index=True)
    student_id: Mapped[int] = mapped_column(ForeignKey("users.id"))
    due_at: Mapped[datetime] = mapped_column(DateTime)
    hard_close_at: Mapped[datetime] = mapped_column(DateTime)
    granted_by_id: Mapped[int] = mapped_column(ForeignKey("users.id"))
    granted_at: Mapped[datetime] = mapped_column(DateTime, default=utcnow)

    student: Mapped[User] = relationship(foreign_keys=[student_id], lazy="joined")
    granted_by: Mapped[User] = relationship(foreign_keys=[granted_by_id], lazy="joined")


class Submission(Base):
    __tablename__ = "submissions"
    # Two submissions racing for one attempt number: the database lets one in (NULLs, outside assignments, never clash).
    __table_args__ = (UniqueConstraint("assignment_id", "student_id", "attempt"),)

    id: Mapped[int] = mapped_column(primary_key=True)
    course_id: Mapped[int] = mapped_column(ForeignKey("courses.id"), index=True)
    student_id: Mapped[int] = mapped_column(ForeignKey("users.id"), index=True)
    lesson: Mapped[str] = mapped_column(String(16))
    sheet: Mapped[dict[str, Any]]
    force_rerun: Mapped[bool] = mapped_column(Boolean, default=False)
    status: Mapped[str] = mapped_column(String(16), default=SubmissionState.RUNNING.value)
    error: Mapped[str | None] = mapped_column(Text)
    created_at: Mapped[datetime] = mapped_column(DateTime, default=utcnow)
    updated_at: Mapped[datetime] = mapped_column(DateTime, default=utcnow)
    grading_at: Mapped[datetime | None] = mapped_column(DateTime)
    graded_at: Mapped[datetime | None] = mapped_column(DateTime)
    # Set for a submission to an assignment: its attempt number there (1, 2, ...) and how late it came, in seconds
    # after the due date that applied to its student (0 when on time).
    assignment_id: Mapped[int | None] = mapped_column(ForeignKey("assignments.id"), index=True)
    attempt: Mapped[int | None] = mapped_column(Integer)
    late_seconds: Mapped[int | None] = mapped_column(Integer)
    # The pool variant it is graded under (issue 34): the student's own at an assignment with a pool, or the variant a
    # pool's measuring submission measures. None: the lesson's shipped cases, as for every submission before pools.
    variant_id: Mapped[int | None] = mapped_column(ForeignKey("pool_variants.id"), index=True)

    student: Mapped[User] = relationship(lazy="joined")
    assignment: Mapped[Assignment | None] = relationship()
    variant: Mapped[PoolVariant | None] = relationship()
    @property
    def part(self) -> str:
        """Which answers its sheet holds: its assignment's part, or the whole sheet."""
        return self.assignment.part if self.assignment is not None else "sheet"

    # The runs that grade it; audit re-runs of its runs (purpose "audit") are kept apart and never graded.
    case_runs: Mapped[list[CaseRun]] = relationship(
        primaryjoin="and_(Submission.id == CaseRun.submission_id, CaseRun.purpose == 'grading')",
        order_by="CaseRun.id", viewonly=True)
    audit_runs: Mapped[list[CaseRun]] = relationship(
        primaryjoin="and_(Submission.id == CaseRun.submission_id, CaseRun.purpose == 'audit')",
        order_by="CaseRun.id", viewonly=True)


class CaseRun(Base):
    """One case of one submission on one backend. `delivery` numbers its messages: a stale message is dropped."""

    __tablename__ = "case_runs"
    __table_args__ = (UniqueConstraint("submission_id", "name"),)

    id: Mapped[int] = mapped_column(primary_key=True)
    submission_id: Mapped[int] = mapped_column(ForeignKey("submissions.id"), index=True)
    name: Mapped[str] = mapped_column(String(64))
    kind: Mapped[str] = mapped_column(String(16))
    backend: Mapped[str] = mapped_column(String(8), index=True)
    precision: Mapped[str] = mapped_column(String(4))
    spec: Mapped[dict[str, Any]]
    status: Mapped[str] = mapped_column(String(16), default=CaseRunState.QUEUED.value, index=True)
    delivery: Mapped[int] = mapped_column(Integer, default=1)
    tries: Mapped[int] = mapped_column(Integer, default=0)
    content_key: Mapped[str | None] = mapped_column(String(64), index=True)
    result_status: Mapped[str | None] = mapped_column(String(16))
    actual_backend: Mapped[str | None] = mapped_column(String(16))
    provenance: Mapped[dict[str, Any] | None] = mapped_column(JSON)
    # The run's metrics, computed once where it ran (rubric.metrics.case_metrics); read by grading and the API.
    metrics: Mapped[dict[str, Any] | None] = mapped_column(JSON)
    artifact_dir: Mapped[str | None] = mapped_column(Text)
    error: Mapped[str | None] = mapped_column(Text)
    stderr_tail: Mapped[str | None] = mapped_column(Text)
    wall_s: Mapped[float | None] = mapped_column(Float)
    measurement_id: Mapped[int | None] = mapped_column(ForeignKey("measurements.id"))
    reused_from_id: Mapped[int | None] = mapped_column(ForeignKey("case_runs.id"))
    worker: Mapped[str | None] = mapped_column(String(255))
    worker_pid: Mapped[int | None] = mapped_column(Integer)
    # "grading" runs decide a submission's grade; "audit" runs re-measure another run on another backend, precision
    # or execution mode for the discrepancy log and never touch a grade.
    purpose: Mapped[str] = mapped_column(String(16), default=CaseRunPurpose.GRADING.value,
                                         server_default=CaseRunPurpose.GRADING.value)
    mode: Mapped[str | None] = mapped_column(String(16))  # requested execution mode; None: the worker's setting
    source_case_run_id: Mapped[int | None] = mapped_column(ForeignKey("case_runs.id"))  # what an audit run re-measures
    requested_by_id: Mapped[int | None] = mapped_column(ForeignKey("users.id"))
    # The physics of the spec without its name, backend and precision: runs with one spec_key measure the same case.
    spec_key: Mapped[str | None] = mapped_column(String(64), index=True)
    lease_until: Mapped[datetime | None] = mapped_column(DateTime)
    queued_at: Mapped[datetime] = mapped_column(DateTime, default=utcnow)
    started_at: Mapped[datetime | None] = mapped_column(DateTime)
    finished_at: Mapped[datetime | None] = mapped_column(DateTime)

    submission: Mapped[Submission] = relationship()


class Measurement(Base):
    """A validated result, reusable by content key (see grader.core.content_key for what the key covers)."""

    __tablename__ = "measurements"

    id: Mapped[int] = mapped_column(primary_key=True)
    content_key: Mapped[str] = mapped_column(String(64), unique=True)
    key_inputs: Mapped[dict[str, Any]]
    # The case run that produced it; a plain id (no FK) so the two tables need no creation-order cycle.
    case_run_id: Mapped[int] = mapped_column(Integer)
    backend: Mapped[str] = mapped_column(String(8))
    provenance: Mapped[dict[str, Any]]
    metrics: Mapped[dict[str, Any] | None] = mapped_column(JSON)
    artifact_dir: Mapped[str] = mapped_column(Text)
    created_at: Mapped[datetime] = mapped_column(DateTime, default=utcnow)


class CaseEvidence(Base):
    """What a case process left for one case run, stored in the transaction that stores the run's result: every
    reader takes it from here, so the folder it was written to is only a cache a worker's host may lose. A run that
    reused a measurement has no row of its own: it reads its measurement's run's (no copy)."""

    __tablename__ = "case_evidence"

    case_run_id: Mapped[int] = mapped_column(ForeignKey("case_runs.id"), primary_key=True)
    # arrays.npz as the case process wrote it; deferred, so listing a run's files never loads it.
    arrays: Mapped[bytes | None] = mapped_column(LargeBinary, deferred=True)
    spec: Mapped[dict[str, Any]]
    provenance: Mapped[dict[str, Any] | None] = mapped_column(JSON)
    metrics: Mapped[dict[str, Any] | None] = mapped_column(JSON)
    # Captured output, whole up to settings.evidence_output_max_bytes, else its tail after a line saying so.
    stdout: Mapped[str | None] = mapped_column(Text)
    stderr: Mapped[str | None] = mapped_column(Text)
    # Bytes of each stored file as served (grader.services.reports.exports.EVIDENCE names): which files the run has.
    sizes: Mapped[dict[str, Any]]
    stored_at: Mapped[datetime] = mapped_column(DateTime, default=utcnow)


class RubricVersion(Base):
    """A rubric version known to the service: shipped with it (rubric/lessons, no publisher, no course: every course
    reads it) or published by an instructor for their course alone, never changed after. Its content is stored whole,
    so a grade's version stays readable whatever the files say later."""

    __tablename__ = "rubric_versions"
    # NULLs are distinct in a unique constraint, so the shipped versions are kept unique by a partial index.
    __table_args__ = (UniqueConstraint("course_id", "lesson", "version", name="uq_rubric_versions_course"),
                      Index("uq_rubric_versions_shipped", "lesson", "version", unique=True,
                            postgresql_where=text("course_id IS NULL"), sqlite_where=text("course_id IS NULL")))

    id: Mapped[int] = mapped_column(primary_key=True)
    course_id: Mapped[int | None] = mapped_column(ForeignKey("courses.id"), index=True)
    lesson: Mapped[str] = mapped_column(String(16))
    version: Mapped[str] = mapped_column(String(32))
    content_hash: Mapped[str] = mapped_column(String(64))
    content: Mapped[dict[str, Any]]
    source: Mapped[str] = mapped_column(String(16))  # "shipped" or "published"
    published_by_id: Mapped[int | None] = mapped_column(ForeignKey("users.id"))
    published_at: Mapped[datetime] = mapped_column(DateTime, default=utcnow)

    published_by: Mapped[User | None] = relationship(lazy="joined")


class Regrade(Base):
    """A committed regrade of one course's lesson under a new rubric version: who committed it, when, what changed."""

    __tablename__ = "regrades"

    id: Mapped[int] = mapped_column(primary_key=True)
    course_id: Mapped[int] = mapped_column(ForeignKey("courses.id"), index=True)
    lesson: Mapped[str] = mapped_column(String(16))
    version: Mapped[str] = mapped_column(String(32))
    committed_by_id: Mapped[int] = mapped_column(ForeignKey("users.id"))
    committed_at: Mapped[datetime] = mapped_column(DateTime, default=utcnow)
    regraded: Mapped[int] = mapped_column(Integer)
    changed: Mapped[int] = mapped_column(Integer)
    # Submissions left on their old grade, with the reason (e.g. a case the new version needs was never measured).
    skipped: Mapped[list[Any]]

    committed_by: Mapped[User] = relationship(lazy="joined")


class Grade(Base):
    """A submission's grade under one rubric version. The current one has superseded_at NULL; a regrade adds a new
    row and marks the old one superseded, never deleting it. At most one current grade per submission (a partial
    unique index): a second grading attempt fails on it instead of grading twice.

    The worker stores a grade (scores, verdicts, feedback) as soon as the rubric has run, with `completed_at` NULL,
    then adds the lab check to its report (`report["check"]`) and sets `completed_at` (worker.grading.complete_grade):
    the score never changes after it is stored, only the check joins it. A grade made any other way
    (a regrade, a checkpoint sheet graded at once) is complete when stored."""

    __tablename__ = "grades"
    __table_args__ = (Index("uq_grades_current", "submission_id", unique=True,
                            postgresql_where=text("superseded_at IS NULL"), sqlite_where=text("superseded_at IS NULL")),)

    id: Mapped[int] = mapped_column(primary_key=True)
    submission_id: Mapped[int] = mapped_column(ForeignKey("submissions.id"), index=True)
    rubric_lesson: Mapped[str] = mapped_column(String(16))
    rubric_version: Mapped[str] = mapped_column(String(32))
    rubric_hash: Mapped[str] = mapped_column(String(64))
    total: Mapped[float] = mapped_column(Float)
    max_total: Mapped[float] = mapped_column(Float)
    report: Mapped[dict[str, Any]]
    execution_s: Mapped[float] = mapped_column(Float, default=0.0)
    created_at: Mapped[datetime] = mapped_column(DateTime, default=utcnow)
    # When its lab check was stored; NULL while it is being evaluated (worker.grading.complete_grade).
    # No default: whoever stores a grade says whether it is complete (the ORM would put a default in for a None).
    completed_at: Mapped[datetime | None] = mapped_column(DateTime)
    superseded_at: Mapped[datetime | None] = mapped_column(DateTime)
    regrade_id: Mapped[int | None] = mapped_column(ForeignKey("regrades.id"))

    regrade: Mapped[Regrade | None] = relationship(lazy="joined")


class AuditEntry(Base):
    """One comparison of two measurements of one case that differ in backend, precision or execution mode.

    Append-only: the database itself refuses an UPDATE or DELETE (a trigger, migration 0004), and neither case run
    it compares is ever deleted or overwritten. `variant` strings read "cpu/32/warm".
    """

    __tablename__ = "audit_entries"

    id: Mapped[int] = mapped_column(primary_key=True)
    created_at: Mapped[datetime] = mapped_column(DateTime, default=utcnow, index=True)
    course_id: Mapped[int | None] = mapped_column(ForeignKey("courses.id"), index=True)
    lesson: Mapped[str] = mapped_column(String(16))
    case: Mapped[str] = mapped_column(String(64))
    spec_key: Mapped[str] = mapped_column(String(64), index=True)
    spec: Mapped[dict[str, Any]]
    left_case_run_id: Mapped[int] = mapped_column(ForeignKey("case_runs.id"))
    right_case_run_id: Mapped[int | None] = mapped_column(ForeignKey("case_runs.id"))
    left_variant: Mapped[str] = mapped_column(String(48))
    right_variant: Mapped[str] = mapped_column(String(48))
    left_provenance: Mapped[dict[str, Any] | None] = mapped_column(JSON)
    right_provenance: Mapped[dict[str, Any] | None] = mapped_column(JSON)
    # identical | within_tolerance | numeric_drift | relation_changed | provenance_violation | not_compared
    classification: Mapped[str] = mapped_column(String(24), index=True)
    summary: Mapped[str] = mapped_column(Text)
    comparison: Mapped[dict[str, Any] | None] = mapped_column(JSON)
    figures_dir: Mapped[str | None] = mapped_column(Text)
    figures: Mapped[list[Any]]
    requested_by_id: Mapped[int | None] = mapped_column(ForeignKey("users.id"))


class Event(Base):
    """Append-only log of state changes, with the time each happened."""

    __tablename__ = "events"

    id: Mapped[int] = mapped_column(primary_key=True)
    submission_id: Mapped[int] = mapped_column(ForeignKey("submissions.id"), index=True)
    case_run_id: Mapped[int | None] = mapped_column(ForeignKey("case_runs.id"))
    state: Mapped[str] = mapped_column(String(32))
    detail: Mapped[str | None] = mapped_column(Text)
    at: Mapped[datetime] = mapped_column(DateTime, default=utcnow)


class LtiRegistration(Base):
    """An LMS (an LTI 1.3 platform) that may launch this tool into one course: its issuer and the client id it gave
    this tool, and the platform's endpoints. Launches from it sign people into `course`."""

    __tablename__ = "lti_registrations"
    __table_args__ = (UniqueConstraint("issuer", "client_id"),)

    id: Mapped[int] = mapped_column(primary_key=True)
    course_id: Mapped[int] = mapped_column(ForeignKey("courses.id"), index=True)
    issuer: Mapped[str] = mapped_column(String(255))
    client_id: Mapped[str] = mapped_column(String(255))
    auth_login_url: Mapped[str] = mapped_column(Text)  # the platform's OIDC authorization endpoint
    auth_token_url: Mapped[str] = mapped_column(Text)  # its OAuth2 token endpoint (grades and roster services)
    key_set_url: Mapped[str] = mapped_column(Text)  # its JWKS: launches are verified against these keys
    created_by_id: Mapped[int | None] = mapped_column(ForeignKey("users.id"))  # None: an operator at the CLI
    created_at: Mapped[datetime] = mapped_column(DateTime, default=utcnow)

    course: Mapped[Course] = relationship(lazy="joined")
    deployments: Mapped[list[LtiDeployment]] = relationship(order_by="LtiDeployment.id", lazy="selectin")


class LtiDeployment(Base):
    """One deployment id of a registration; a launch naming any other is refused."""

    __tablename__ = "lti_deployments"
    __table_args__ = (UniqueConstraint("registration_id", "deployment_id"),)

    id: Mapped[int] = mapped_column(primary_key=True)
    registration_id: Mapped[int] = mapped_column(ForeignKey("lti_registrations.id"), index=True)
    deployment_id: Mapped[str] = mapped_column(String(255))


class LtiKey(Base):
    """The tool's own RSA key pair (it signs the tool's messages to platforms). The newest unretired key signs; a
    retired key's public half stays in /lti/jwks until `retired_at` + settings' grace, so tokens signed just before a
    rotation still verify."""

    __tablename__ = "lti_keys"

    id: Mapped[int] = mapped_column(primary_key=True)
    kid: Mapped[str] = mapped_column(String(64), unique=True)
    private_key_pem: Mapped[str] = mapped_column(Text)
    public_jwk: Mapped[dict[str, Any]]
    created_at: Mapped[datetime] = mapped_column(DateTime, default=utcnow)
    retired_at: Mapped[datetime | None] = mapped_column(DateTime)


class LtiIdentity(Base):
    """Who a user is in an LMS: the launch's `sub` under one registration. A later launch finds the same user."""

    __tablename__ = "lti_identities"
    __table_args__ = (UniqueConstraint("registration_id", "sub"),)

    id: Mapped[int] = mapped_column(primary_key=True)
    registration_id: Mapped[int] = mapped_column(ForeignKey("lti_registrations.id"), index=True)
    sub: Mapped[str] = mapped_column(String(255))
    user_id: Mapped[int] = mapped_column(ForeignKey("users.id"), index=True)
    created_at: Mapped[datetime] = mapped_column(DateTime, default=utcnow)

    user: Mapped[User] = relationship(lazy="joined")


class LtiLaunchState(Base):
    """One OIDC login this tool started: the state and nonce it sent the platform. The launch that answers it uses
    it once (`used_at`); a replayed or late launch finds it used or expired."""

    __tablename__ = "lti_launch_states"

    id: Mapped[int] = mapped_column(primary_key=True)
    registration_id: Mapped[int] = mapped_column(ForeignKey("lti_registrations.id"), index=True)
    state: Mapped[str] = mapped_column(String(128), unique=True)
    nonce: Mapped[str] = mapped_column(String(128), unique=True)
    created_at: Mapped[datetime] = mapped_column(DateTime, default=utcnow)
    expires_at: Mapped[datetime] = mapped_column(DateTime)
    used_at: Mapped[datetime | None] = mapped_column(DateTime)
    # A deep-linking launch: its deployment and the platform's deep-linking settings, until the instructor's choice
    # of an assignment is answered (then None again: one answer per launch).
    deployment_id: Mapped[str | None] = mapped_column(String(255))
    deep_link: Mapped[dict[str, Any] | None] = mapped_column(JSON)

    registration: Mapped[LtiRegistration] = relationship(lazy="joined")


class Draft(Base):
    """A student's unsent prediction sheet for one assignment (assignment_id None: a free sheet), saved as they type so
    it outlives the browser; one per user and assignment. `sheet` is what the form holds, valid or not yet."""

    __tablename__ = "drafts"
    # NULLs never clash in a unique constraint: a free sheet's one draft per user is the partial index's.
    __table_args__ = (UniqueConstraint("user_id", "assignment_id"),
                      Index("uq_drafts_free_sheet", "user_id", unique=True,
                            postgresql_where=text("assignment_id IS NULL"), sqlite_where=text("assignment_id IS NULL")))

    id: Mapped[int] = mapped_column(primary_key=True)
    user_id: Mapped[int] = mapped_column(ForeignKey("users.id"), index=True)
    assignment_id: Mapped[int | None] = mapped_column(ForeignKey("assignments.id"), index=True)
    sheet: Mapped[dict[str, Any]]
    updated_at: Mapped[datetime] = mapped_column(DateTime, default=utcnow)


class LtiContext(Base):
    """An LMS course (the launch's context) under a registration, with its grades service (AGS) and roster service
    (NRPS) endpoints as the last launch from it gave them."""

    __tablename__ = "lti_contexts"
    __table_args__ = (UniqueConstraint("registration_id", "context_id"),)

    id: Mapped[int] = mapped_column(primary_key=True)
    registration_id: Mapped[int] = mapped_column(ForeignKey("lti_registrations.id"), index=True)
    context_id: Mapped[str] = mapped_column(String(255))
    lineitems_url: Mapped[str | None] = mapped_column(Text)
    scopes: Mapped[list[Any]] = mapped_column(JSON, default=list)
    memberships_url: Mapped[str | None] = mapped_column(Text)  # its roster service (NRPS)
    updated_at: Mapped[datetime] = mapped_column(DateTime, default=utcnow)

    registration: Mapped[LtiRegistration] = relationship(lazy="joined")


class LtiLineItem(Base):
    """The LMS gradebook column of one assignment in one LMS course: created once, reused after."""

    __tablename__ = "lti_line_items"
    __table_args__ = (UniqueConstraint("context_id", "assignment_id"),)

    id: Mapped[int] = mapped_column(primary_key=True)
    context_id: Mapped[int] = mapped_column(ForeignKey("lti_contexts.id"), index=True)
    assignment_id: Mapped[int] = mapped_column(ForeignKey("assignments.id"), index=True)
    url: Mapped[str] = mapped_column(Text)


class LtiScore(Base):
    """The last score sent (or tried) for one student on one line item: a send repeats only when the score changed
    or the last try failed; `error` is what the instructor sees of a failure."""

    __tablename__ = "lti_scores"
    __table_args__ = (UniqueConstraint("line_item_id", "user_id"),)

    id: Mapped[int] = mapped_column(primary_key=True)
    line_item_id: Mapped[int] = mapped_column(ForeignKey("lti_line_items.id"), index=True)
    user_id: Mapped[int] = mapped_column(ForeignKey("users.id"), index=True)
    submission_id: Mapped[int] = mapped_column(ForeignKey("submissions.id"))
    score_given: Mapped[float] = mapped_column(Float)
    score_maximum: Mapped[float] = mapped_column(Float)
    status: Mapped[str] = mapped_column(String(8))  # sent | failed
    error: Mapped[str | None] = mapped_column(Text)
    tries: Mapped[int] = mapped_column(Integer, default=0)
    sent_at: Mapped[datetime] = mapped_column(DateTime, default=utcnow)


class Override(Base):
    """An instructor's score for one item of one submission, with the comment that says why. The measured verdict is
    never changed: the grade it produced keeps it beside the override (grader.services.submissions.overrides). A later override
    of the same item supersedes this one, which is kept; at most one is current per item (a partial unique index)."""

    __tablename__ = "overrides"
    __table_args__ = (Index("uq_overrides_current", "submission_id", "item_id", unique=True,
                            postgresql_where=text("superseded_at IS NULL"),
                            sqlite_where=text("superseded_at IS NULL")),)

    id: Mapped[int] = mapped_column(primary_key=True)
    submission_id: Mapped[int] = mapped_column(ForeignKey("submissions.id"), index=True)
    item_id: Mapped[str] = mapped_column(String(16))
    score: Mapped[float] = mapped_column(Float)
    comment: Mapped[str] = mapped_column(Text)
    by_id: Mapped[int] = mapped_column(ForeignKey("users.id"))
    at: Mapped[datetime] = mapped_column(DateTime, default=utcnow)
    # The grade this override produced (it supersedes the one it overrode).
    grade_id: Mapped[int | None] = mapped_column(ForeignKey("grades.id"))
    superseded_at: Mapped[datetime | None] = mapped_column(DateTime)
    superseded_by_id: Mapped[int | None] = mapped_column(ForeignKey("overrides.id"))

    by: Mapped[User] = relationship(lazy="joined")


class ReviewRequest(Base):
    """A student's request that an instructor review one item of a graded submission. Open while `answered_at` is
    NULL; at most one open request per submission and item (a partial unique index). Answered requests are kept."""

    __tablename__ = "review_requests"
    __table_args__ = (Index("uq_review_requests_open", "submission_id", "item_id", unique=True,
                            postgresql_where=text("answered_at IS NULL"), sqlite_where=text("answered_at IS NULL")),)

    id: Mapped[int] = mapped_column(primary_key=True)
    submission_id: Mapped[int] = mapped_column(ForeignKey("submissions.id"), index=True)
    item_id: Mapped[str] = mapped_column(String(16))
    student_id: Mapped[int] = mapped_column(ForeignKey("users.id"))
    message: Mapped[str] = mapped_column(Text)
    created_at: Mapped[datetime] = mapped_column(DateTime, default=utcnow)
    answer: Mapped[str | None] = mapped_column(Text)
    answered_by_id: Mapped[int | None] = mapped_column(ForeignKey("users.id"))
    answered_at: Mapped[datetime | None] = mapped_column(DateTime)
    override_id: Mapped[int | None] = mapped_column(ForeignKey("overrides.id"))  # set when answered with one

    student: Mapped[User] = relationship(foreign_keys=[student_id], lazy="joined")
    answered_by: Mapped[User | None] = relationship(foreign_keys=[answered_by_id], lazy="joined")
    submission: Mapped[Submission] = relationship()
    override: Mapped[Override | None] = relationship()


class RubricSignoff(Base):
    """An instructor's sign-off of one rubric version's content for their course: who, when, and a note. A row of its
    own, so signing never changes the version's content or hash; `content_hash` names the content signed."""

    __tablename__ = "rubric_signoffs"

    id: Mapped[int] = mapped_column(primary_key=True)
    version_id: Mapped[int] = mapped_column(ForeignKey("rubric_versions.id"), index=True)
    course_id: Mapped[int] = mapped_column(ForeignKey("courses.id"), index=True)
    content_hash: Mapped[str] = mapped_column(String(64))
    user_id: Mapped[int] = mapped_column(ForeignKey("users.id"))
    at: Mapped[datetime] = mapped_column(DateTime, default=utcnow)
    note: Mapped[str] = mapped_column(Text)

    user: Mapped[User] = relationship(lazy="joined")


class CourseChange(Base):
    """One change to a course's set-up (its time zone, an assignment, an extension, a release, the roster, a sign-in
    link), with who made it and when. Written by the service that makes the change, in the same transaction, so the
    pages, the API and the command line all record; never updated. `detail` holds the values before and after
    (never a token or a link's secret)."""

    __tablename__ = "course_changes"

    id: Mapped[int] = mapped_column(primary_key=True)
    course_id: Mapped[int] = mapped_column(ForeignKey("courses.id"), index=True)
    by_id: Mapped[int] = mapped_column(ForeignKey("users.id"))
    at: Mapped[datetime] = mapped_column(DateTime, default=utcnow)
    kind: Mapped[str] = mapped_column(String(32))  # grader.services.setup.course_changes.ChangeKind
    assignment_id: Mapped[int | None] = mapped_column(ForeignKey("assignments.id"), index=True)
    summary: Mapped[str] = mapped_column(Text)
    detail: Mapped[dict[str, Any]] = mapped_column(JSON, default=dict)

    by: Mapped[User] = relationship(lazy="joined")


class LtiOutbox(Base):
    """An assignment whose counted scores changed (graded, released, overridden, regraded) and are due for the LMS
    gradebooks: marked in the change's own transaction, sent by the reconciler's pass (grader.services.lti.outbox).
    `due_at` NULL: nothing to send. `attempts` counts the failed passes since the last whole send; each pushes
    `due_at` further out (backoff, capped), and `last_error` is what the instructor's LTI page shows of it."""

    __tablename__ = "lti_outbox"

    id: Mapped[int] = mapped_column(primary_key=True)
    assignment_id: Mapped[int] = mapped_column(ForeignKey("assignments.id"), unique=True)
    changed_at: Mapped[datetime] = mapped_column(DateTime, default=utcnow)
    due_at: Mapped[datetime | None] = mapped_column(DateTime, index=True)
    attempts: Mapped[int] = mapped_column(Integer, default=0)
    tried_at: Mapped[datetime | None] = mapped_column(DateTime)
    last_error: Mapped[str | None] = mapped_column(Text)
    waiting: Mapped[str | None] = mapped_column(Text)  # why some student's score is held back (withheld items)

    assignment: Mapped[Assignment] = relationship()


class VariantPool(Base):
    """An assignment's pool of lab variants (issue 34), drawn from a seed out of a reviewed variant space
    (rubric.variants.draw_pool). Each variant's lesson runs are measured and its lab check evaluated before students
    get one; `ready_at` is set once no variant is still measuring. `rejected` keeps the draws refused by the draw."""

    __tablename__ = "variant_pools"

    id: Mapped[int] = mapped_column(primary_key=True)
    assignment_id: Mapped[int] = mapped_column(ForeignKey("assignments.id"), unique=True)
    lesson: Mapped[str] = mapped_column(String(16))
    space_version: Mapped[str] = mapped_column(String(32))
    space_hash: Mapped[str] = mapped_column(String(64))
    rubric_version: Mapped[str] = mapped_column(String(32))  # the course's version the variants are checked under
    seed: Mapped[int] = mapped_column(Integer)
    k: Mapped[int] = mapped_column(Integer)  # the variants to keep (issue 47), not the number drawn
    # The most variants the pool may draw and measure to keep K (NULL: a pool from before issue 47, which drew K).
    draw_budget: Mapped[int | None] = mapped_column(Integer)
    # How many must be kept before a student gets one (NULL: K, as before issue 47).
    minimum: Mapped[int | None] = mapped_column(Integer)
    state: Mapped[str] = mapped_column(String(16))  # grader.core.states.PoolState
    rejected: Mapped[list[Any]] = mapped_column(JSON, default=list)
    created_by_id: Mapped[int] = mapped_column(ForeignKey("users.id"))
    created_at: Mapped[datetime] = mapped_column(DateTime, default=utcnow)
    ready_at: Mapped[datetime | None] = mapped_column(DateTime)

    assignment: Mapped[Assignment] = relationship()
    variants: Mapped[list[PoolVariant]] = relationship(order_by="PoolVariant.position", back_populates="pool")


class PoolVariant(Base):
    """One drawn variant of a pool: its id (`name`, "v2026-3"), every lesson parameter, and whether it is kept. Its
    lesson runs are the case runs of one measuring submission (`submission_id`, a plain id: submissions point here,
    so no creation-order cycle), reused by content key by every student who gets it."""

    __tablename__ = "pool_variants"
    __table_args__ = (UniqueConstraint("pool_id", "name"),)

    id: Mapped[int] = mapped_column(primary_key=True)
    pool_id: Mapped[int] = mapped_column(ForeignKey("variant_pools.id"), index=True)
    name: Mapped[str] = mapped_column(String(32))
    position: Mapped[int] = mapped_column(Integer)
    parameters: Mapped[dict[str, Any]]
    digest: Mapped[str] = mapped_column(String(16))
    state: Mapped[str] = mapped_column(String(16))  # grader.core.states.VariantState
    reason: Mapped[str | None] = mapped_column(Text)  # why it was dropped, shown to staff
    submission_id: Mapped[int | None] = mapped_column(Integer, index=True)
    check: Mapped[dict[str, Any] | None] = mapped_column(JSON)  # the lab check of its measured runs
    decided_at: Mapped[datetime | None] = mapped_column(DateTime)

    pool: Mapped[VariantPool] = relationship(back_populates="variants")


class StudentVariant(Base):
    """The one variant of an assignment's pool a student works on, fixed at their first form view or submission."""

    __tablename__ = "student_variants"
    __table_args__ = (UniqueConstraint("assignment_id", "student_id"),)

    id: Mapped[int] = mapped_column(primary_key=True)
    assignment_id: Mapped[int] = mapped_column(ForeignKey("assignments.id"), index=True)
    student_id: Mapped[int] = mapped_column(ForeignKey("users.id"), index=True)
    variant_id: Mapped[int] = mapped_column(ForeignKey("pool_variants.id"), index=True)
    assigned_at: Mapped[datetime] = mapped_column(DateTime, default=utcnow)

    variant: Mapped[PoolVariant] = relationship(lazy="joined")


class CopyFlag(Base):
    """Evidence that a variant submission's answers fit another variant's expected answers rather than its own
    (rubric.copying.copy_evidence), stored when it is graded; never changes a grade. Staff only."""

    __tablename__ = "copy_flags"

    id: Mapped[int] = mapped_column(primary_key=True)
    submission_id: Mapped[int] = mapped_column(ForeignKey("submissions.id"), index=True)
    grade_id: Mapped[int] = mapped_column(ForeignKey("grades.id"))
    variant_id: Mapped[int] = mapped_column(ForeignKey("pool_variants.id"))  # the other variant the answers fit
    items: Mapped[list[Any]]
    own_expected: Mapped[dict[str, Any]]
    other_expected: Mapped[dict[str, Any]]
    summary: Mapped[str] = mapped_column(Text)
    created_at: Mapped[datetime] = mapped_column(DateTime, default=utcnow)

    submission: Mapped[Submission] = relationship()
    variant: Mapped[PoolVariant] = relationship(lazy="joined")
