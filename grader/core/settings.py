"""One Settings class for the API, the Celery workers and the CLI: embedded defaults, env vars for deployment."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Literal

from limits import parse
from pydantic import Field, field_validator, model_validator
from pydantic_settings import BaseSettings, NoDecode, SettingsConfigDict

PLACEHOLDERS = ("changeme", "change-me", "password@", ":postgres@")


class Settings(BaseSettings):
    """Defaults run embedded (SQLite database, kombu filesystem broker, files under DATA_DIR); env vars deploy."""

    model_config = SettingsConfigDict(env_prefix="", extra="ignore")

    environment: Literal["development", "production"] = "development"
    data_dir: Path = Path("var/grader")
    # Empty means "derive from data_dir": the embedded default needs no server at all.
    database_url: str = ""
    broker_url: str = ""
    artifacts_dir: Path | None = None
    # A case run's captured stdout and stderr are each stored whole up to this many bytes, else their tail.
    evidence_output_max_bytes: int = Field(1_000_000, ge=1_000)
    # Wall-clock limit of one case process; Celery's soft/hard limits sit a margin above it.
    case_time_limit_s: float = Field(900.0, gt=0)
    # Resident memory one case process may hold (MB; 0: no limit): past it the process is stopped and the case fails
    # "memory limit exceeded", a bound of the service. The largest case measured (docs/operator.md) plus a margin.
    case_memory_limit_mb: int = Field(3072, ge=0)
    # A running case run whose worker stopped answering is re-queued this long after its time limit.
    lease_margin_s: float = Field(120.0, ge=0)
    # A queued case run whose message may have been lost (broker restart) is re-sent after this long.
    queue_lease_s: float = Field(1800.0, gt=0)
    # Retries for infrastructure failures only (database, broker, disk); a failed case is never retried elsewhere.
    max_infra_retries: int = Field(3, ge=0, le=10)
    execution_mode: Literal["warm", "isolated"] = "warm"
    # Days added to the system clock by the service's one clock (grader.core.clock): a rehearsal of a term, or the
    # suite run as if on another date (CLOCK_SHIFT_DAYS=365 make test). 0 in any real deployment.
    clock_shift_days: float = 0.0
    # Flat memory measured over 350 reused-scene cases (928 MB), so recycling is a safety bound, not a need.
    warm_max_cases: int = Field(500, ge=1)
    # A warm case process resets and reuses a scene already built for a case of the same structure (same dt,
    # substeps, bodies) instead of building anew; only friction and per-case loop settings change. On because
    # tests/worker/test_scene_reuse.py proves the arrays equal, sample for sample, to a fresh scene's.
    scene_reuse: bool = True
    # A worker process starts its warm case process when it starts, and that process builds the lesson's scene
    # structures (the lessons' warm_up_cases: worker.warm_process.warm_up_cases) on this backend before it reads a
    # case: the first case after a deploy or a restart no longer pays ~15 s of import, init and kernel loading.
    # "off": started on the first case instead. A ROCm worker sets rocm (docker-compose.yml); a warm-up that fails is
    # logged, and the first case then fails visibly as it would have.
    warm_up_backend: Literal["cpu", "rocm", "cuda", "off"] = "cpu"
    # Case slots per worker (Celery prefork processes, each with its own warm case process): a submission's runs
    # execute side by side. 0: one per core this process may run on, no more than the host's memory holds at
    # case_memory_limit_mb each (worker.celery_app.worker_concurrency). A case steps on one thread (docs/benchmark.md).
    worker_concurrency: int = Field(0, ge=0, le=256)
    # The API runs sync handlers and dependencies on this many threads (anyio's default is 40) and admits this many
    # requests at once; the rest wait unserved, holding no thread and no connection. Each engine's pool keeps as many
    # connections, so an admitted request never waits on the pool while holding a connection that a request waiting
    # for a thread needs: with SQLAlchemy's default pool (5 + 10) that deadlock showed as 30 s timeouts at 50 clients.
    api_threads: int = Field(40, ge=1, le=1000)
    # Connections beyond api_threads, for the rest of a process (the embedded reconciler thread, a worker's tasks).
    # A PostgreSQL server needs max_connections >= (api_threads + db_pool_overflow) per API process + the workers'.
    db_pool_overflow: int = Field(10, ge=0, le=1000)
    max_body_bytes: int = Field(1_000_000, gt=0)
    # A sheet is about 6 levels deep; deeper JSON is refused before anything walks it.
    max_json_depth: int = Field(32, ge=4, le=200)
    # A request's whole body must arrive within this long (408 otherwise) before it takes one of the api_threads
    # admission slots: stalled bodies once held every slot and /v1/health timed out.
    body_deadline_s: float = Field(10.0, gt=0, le=300)
    # Requests one client address may have in flight at once (429 beyond), from arrival to answer. Behind a proxy,
    # the app must trust its X-Forwarded-For (FORWARDED_ALLOW_IPS below), or every client counts as the proxy.
    client_max_in_flight: int = Field(20, ge=1, le=10_000)
    # The proxies in front of the API (comma-separated addresses or networks, "*" for any): only a request from one
    # of them has its client address and scheme taken from X-Forwarded-For / X-Forwarded-Proto
    # (grader.web.admission.TrustedProxies), for every per-address limit and the access log. Empty, the embedded
    # default: none, so a client on loopback cannot name other addresses to escape them. The variable uvicorn reads.
    forwarded_allow_ips: Annotated[list[str], NoDecode] = Field(default_factory=list)
    # Per API token, in the `limits` notation ("10/minute", "100/hour"): each submission queues real Genesis runs.
    rate_limit_submissions: str = "10/minute"
    # Where the counts live: memory:// for one API process (embedded); redis://... when several API processes serve.
    rate_limit_storage_url: str = "memory://"
    # A page sign-in lasts until it has been idle this long, and never beyond the absolute lifetime (nor its token's
    # expiry): a cookie left on a shared lab machine stops working the same day, a stolen one within a week.
    session_idle_s: float = Field(12 * 3600.0, gt=0)
    session_lifetime_s: float = Field(7 * 24 * 3600.0, gt=0)
    # A new API token expires after this many days (`grader admin token --expires-in` chooses per token): about a
    # term, so a leaked token does not outlive the course.
    token_lifetime_days: int = Field(180, ge=1, le=3650)
    # A student's sign-in link (roster import, re-issue) works once, within this many days of being issued.
    sign_in_link_days: int = Field(14, ge=1, le=365)
    # Per staff member, audit re-runs asked for (each queues a fresh Genesis run that no reuse can shorten).
    rate_limit_audit_reruns: str = "20/hour"
    # Per person, counted at every door (grader.services.identity.quotas): draft saves (the sheet form saves as the student
    # types, about one a second at most), review requests, and per client address failed sign-ins (wrong tokens) and
    # look-ups of unknown sign-in links (guessing), which a correct sign-in or link never spends.
    rate_limit_draft_saves: str = "120/minute"
    rate_limit_review_requests: str = "20/hour"
    rate_limit_sign_in_failures: str = "20/10 minutes"
    rate_limit_link_guesses: str = "20/10 minutes"
    # Case runs one student may have waiting or running at once (a whole sheet queues at most 9).
    student_waiting_runs_max: int = Field(27, ge=1)
    # Variant pools (grader.services.setup.variants): the most variants one pool may ask for (K: each queues a measuring
    # submission of 9 case runs; the variant space yields 64 at most), and how many pools may be measured at once per
    # instructor and per course (a pool is measuring until every variant is kept or dropped). Pool runs wait at the
    # lowest priority (grader.core.lifecycle.POOL_PRIORITY), behind every student's.
    variant_pool_k_max: int = Field(64, ge=1, le=64)
    variant_pools_measuring_per_instructor: int = Field(1, ge=1)
    variant_pools_measuring_per_course: int = Field(2, ge=1)
    # The service's public URL (https://grader.example.edu): the report link in the comment of each score the
    # reconciler's pass sends to an LMS gradebook (grader.services.lti.outbox). Empty: the comment names the attempt.
    public_url: str = ""
    # Every URL the server fetches (LTI key sets, token endpoints, gradebooks, rosters: grader.core.outbound) is
    # https to a public address. OUTBOUND_ALLOW_HTTP lets plain http through (tests on loopback, a local trial);
    # OUTBOUND_ALLOWED_HOSTS (comma-separated host names, addresses or networks, each optionally :port) lets a
    # platform inside a private network through. Each fetch ends within the timeout and reads at most the bytes.
    outbound_allow_http: bool = False
    outbound_allowed_hosts: Annotated[list[str], NoDecode] = Field(default_factory=list)
    outbound_timeout_s: float = Field(10.0, gt=0, le=120)
    outbound_max_bytes: int = Field(2_000_000, ge=1_000)
    # Members one course's LMS roster sync reads at most (every entry of every page, all roles): past it the sync
    # stops with a 409 naming this cap, keeping the pages before (grader.services.lti.roster).
    lti_roster_max_members: int = Field(10_000, ge=1, le=1_000_000)
    # Per client address, anonymous LTI logins (/lti/login): each stores a one-time state until it expires.
    rate_limit_lti_logins: str = "30/minute"
    # API processes the container starts (uvicorn --workers; docker-compose.yml sets 2): each holds its own
    # api_threads and database pool. More than one needs RATE_LIMIT_STORAGE_URL on Redis (refused otherwise): in
    # memory, each process would count its own share of every token's submissions.
    api_workers: int = Field(1, ge=1, le=64)

    @field_validator("rate_limit_submissions", "rate_limit_audit_reruns", "rate_limit_draft_saves",
                     "rate_limit_review_requests", "rate_limit_sign_in_failures", "rate_limit_link_guesses")
    @classmethod
    def _a_rate_limit(cls, value: str) -> str:
        parse(value)  # raises ValueError naming the bad notation
        return value

    @field_validator("rate_limit_lti_logins")
    @classmethod
    def _an_lti_login_limit(cls, value: str) -> str:
        parse(value)  # raises ValueError naming the bad notation
        return value

    @field_validator("outbound_allowed_hosts", "forwarded_allow_ips", mode="before")
    @classmethod
    def _comma_separated(cls, value):
        return [x.strip() for x in value.split(",") if x.strip()] if isinstance(value, str) else value

    @model_validator(mode="after")
    def _derive_and_refuse_placeholders(self) -> "Settings":
        if not self.database_url:
            self.database_url = f"sqlite:///{(self.data_dir / 'grader.db').absolute()}"
        if not self.broker_url:
            self.broker_url = "filesystem://"  # folders under data_dir/broker; see worker.celery_app
        if self.artifacts_dir is None:
            self.artifacts_dir = self.data_dir / "artifacts"
        self.artifacts_dir = self.artifacts_dir.absolute()
        if self.api_workers > 1 and self.rate_limit_storage_url.startswith("memory"):
            raise ValueError("api_workers: more than one API process needs rate_limit_storage_url on Redis "
                             "(redis://...), so that every process counts the same submissions")
        if self.environment == "production":
            for name in ("database_url", "broker_url"):
                value = getattr(self, name).lower()
                if value.startswith(("sqlite", "sqla+sqlite", "filesystem")) or any(p in value for p in PLACEHOLDERS):
                    raise ValueError(f"{name}: an embedded or placeholder value is refused in production")
        return self

    @property
    def lease_s(self) -> float:
        return self.case_time_limit_s + self.lease_margin_s

    @property
    def embedded(self) -> bool:
        return self.database_url.startswith("sqlite")


settings = Settings()
