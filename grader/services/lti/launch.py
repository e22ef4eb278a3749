"""LTI 1.3 as a tool: platform registrations, the tool's own keys, the one-time OIDC state and nonce, who a validated
launch signs in, the assignment a deep link opens, the counted scores sent back (AGS) and the roster synced (NRPS).
The protocol (token format, signatures, claims, the services' requests) is pylti1p3's; this module is its storage
(`RegistrationConf`, `LaunchStates`) and what it means here. The web layer (grader.pages.lti.launch) adapts it to FastAPI."""

from __future__ import annotations

import hashlib
import re
from dataclasses import dataclass
from datetime import timedelta
from typing import Any
from urllib.parse import urljoin, urlsplit

import requests
from limits import parse
from jwcrypto.jwk import JWK
from pylti1p3.assignments_grades import AssignmentsGradesService
from pylti1p3.deep_link import DeepLink
from pylti1p3.deep_link_resource import DeepLinkResource
from pylti1p3.deployment import Deployment
from pylti1p3.exception import LtiException, LtiServiceException
from pylti1p3.grade import Grade as LibraryGrade
from pylti1p3.lineitem import LineItem
from pylti1p3.registration import Registration
from pylti1p3.service_connector import ServiceConnector
from pylti1p3.session import SessionService
from pylti1p3.tool_config import ToolConfAbstract
from sqlalchemy import delete, select, update
from sqlalchemy.orm import Session

from grader.core import outbound
from grader.core.lti_outbox import scores_changed
from grader.core.states import Role
from grader.core.models import (Assignment, Course, LtiContext, LtiDeployment, LtiIdentity, LtiKey, LtiLaunchState,
                           LtiLineItem, LtiRegistration, LtiScore, User, utcnow)
from grader.services.setup.assignments import counted_grades
from grader.services.identity import quotas
from grader.services.errors import Conflict, DomainError, Invalid, Refused
from grader.services.submissions.visibility import grade_view
from grader.core.settings import settings
from grader.services.identity import access

# The platform has this long between the tool's login redirect and its launch POST.
STATE_LIFETIME = timedelta(minutes=10)
# A rotated-out key stays in the tool's JWKS this long: what it signed just before the rotation still verifies.
RETIRED_KEY_KEPT = timedelta(days=2)
# Pages (of a roster, of line items) one connector reads at most: a platform's `next` links must end.
MAX_PAGES = 200

CLAIM = "https://purl.imsglobal.org/spec/lti/claim/"
INSTRUCTOR_ROLES = ("http://purl.imsglobal.org/vocab/lis/v2/membership#Instructor", "Instructor")
LEARNER_ROLES = ("http://purl.imsglobal.org/vocab/lis/v2/membership#Learner", "Learner")
TA_ROLE = "http://purl.imsglobal.org/vocab/lis/v2/membership/Instructor#TeachingAssistant"


class LaunchRefused(DomainError):
    """A login or launch this tool does not accept: the error page (400) names the part and why; nothing is stored."""

    def __init__(self, field: str, rule: str):
        super().__init__("LTI launch refused", [{"field": field, "rule": rule}])


# --- registrations -----------------------------------------------------------------------------------------------

def _url(field: str, value: str, errors: list[dict[str, str]], *, fetched: bool = True) -> str:
    """The URL, with its refusal added to `errors`: a URL the server fetches must pass the outbound policy
    (grader.core.outbound, checked again at every fetch); the login URL, where only browsers go, must be https."""
    value = (value or "").strip()
    parts = urlsplit(value)
    if parts.scheme not in ("http", "https") or not parts.netloc:
        errors.append({"field": field, "rule": "must be an absolute http(s) URL"})
    elif fetched and (refusal := outbound.url_refusal(value)):
        errors.append({"field": field, "rule": refusal})
    elif not fetched and parts.scheme == "http" and not settings.outbound_allow_http:
        errors.append({"field": field, "rule": "must be an https URL (plain http is refused unless the operator "
                                               "allows it: OUTBOUND_ALLOW_HTTP)"})
    return value


def create_registration(*, session: Session, course: Course, issuer: str, client_id: str, deployment_ids: list[str],
                        auth_login_url: str, auth_token_url: str, key_set_url: str,
                        by: User | None = None) -> LtiRegistration:
    """Registers a platform for a course (by its instructor, or an operator when `by` is None). Each bad field is
    named in one Invalid; a second registration of one issuer and client id is a Conflict. The caller commits."""
    errors: list[dict[str, str]] = []
    issuer, client_id = (issuer or "").strip(), (client_id or "").strip()
    if not issuer or len(issuer) > 255:
        errors.append({"field": "issuer", "rule": "must be 1 to 255 characters (the platform's iss)"})
    if not client_id or len(client_id) > 255:
        errors.append({"field": "client_id", "rule": "must be 1 to 255 characters (the id the platform gave the tool)"})
    deployments = [d.strip() for d in deployment_ids or [] if d and d.strip()]
    if not deployments or any(len(d) > 255 for d in deployments):
        errors.append({"field": "deployment_ids",
                       "rule": "must name at least one deployment id of 1 to 255 characters"})
    urls = {"auth_login_url": _url("auth_login_url", auth_login_url, errors, fetched=False),
            "auth_token_url": _url("auth_token_url", auth_token_url, errors),
            "key_set_url": _url("key_set_url", key_set_url, errors)}
    if errors:
        raise Invalid("registration refused", errors)
    if session.scalar(select(LtiRegistration).where(LtiRegistration.issuer == issuer,
                                                    LtiRegistration.client_id == client_id)) is not None:
        raise Conflict(f"the platform {issuer} already registered client id {client_id}")
    row = LtiRegistration(course_id=course.id, issuer=issuer, client_id=client_id, created_by_id=by.id if by else None,
                          **urls)
    session.add(row)
    session.flush()
    for deployment_id in dict.fromkeys(deployments):
        session.add(LtiDeployment(registration_id=row.id, deployment_id=deployment_id))
    session.flush()
    session.refresh(row)
    return row


def course_registrations(*, session: Session, course: Course) -> list[LtiRegistration]:
    return list(session.scalars(select(LtiRegistration).where(LtiRegistration.course_id == course.id)
                                .order_by(LtiRegistration.id)))


# --- the tool's keys ---------------------------------------------------------------------------------------------

def _new_key() -> LtiKey:
    jwk = JWK.generate(kty="RSA", size=2048)
    kid = jwk.thumbprint()  # pylti1p3 names the key it signs with by its thumbprint
    public = jwk.export_public(as_dict=True) | {"kid": kid, "alg": "RS256", "use": "sig"}
    return LtiKey(kid=kid, private_key_pem=jwk.export_to_pem(private_key=True, password=None).decode(),
                  public_jwk=public)


def signing_key(*, session: Session) -> LtiKey:
    """The key the tool signs with now; the first one is made on first use (the caller commits)."""
    key = session.scalar(select(LtiKey).where(LtiKey.retired_at.is_(None)).order_by(LtiKey.id.desc()))
    if key is None:
        key = _new_key()
        session.add(key)
        session.flush()
    return key


def rotate_key(*, session: Session) -> LtiKey:
    """A new signing key; the ones before it are retired, their public halves published for RETIRED_KEY_KEPT more."""
    session.execute(update(LtiKey).where(LtiKey.retired_at.is_(None)).values(retired_at=utcnow()))
    key = _new_key()
    session.add(key)
    session.flush()
    return key


def public_jwks(*, session: Session) -> dict[str, list[dict[str, Any]]]:
    """The tool's JWKS: the signing key and any retired within RETIRED_KEY_KEPT, newest first."""
    signing_key(session=session)
    since = utcnow() - RETIRED_KEY_KEPT
    keys = session.scalars(select(LtiKey).where((LtiKey.retired_at.is_(None)) | (LtiKey.retired_at > since))
                           .order_by(LtiKey.id.desc()))
    return {"keys": [key.public_jwk for key in keys]}


# --- pylti1p3's storage ------------------------------------------------------------------------------------------

class RegistrationConf(ToolConfAbstract):
    """pylti1p3's tool configuration, read from the registrations table. `found` is the row the last lookup
    matched: the launch's registration once pylti1p3 has validated it."""

    def __init__(self, session: Session):
        self.session = session
        self.found: LtiRegistration | None = None
        self.unmatched: str | None = None  # what no registration matched: "issuer", or its "client_id"

    def check_iss_has_one_client(self, iss: str) -> bool:
        return False  # one issuer may register several client ids: always look up by both

    def check_iss_has_many_clients(self, iss: str) -> bool:
        return True

    def find_registration_by_issuer(self, iss: str, *args, **kwargs) -> Registration | None:
        return self.find_registration_by_params(iss, None)

    def find_registration_by_params(self, iss: str, client_id: str | None, *args, **kwargs) -> Registration | None:
        query = select(LtiRegistration).where(LtiRegistration.issuer == iss)
        if client_id:
            query = query.where(LtiRegistration.client_id == client_id)
        rows = list(self.session.scalars(query.limit(2)))
        # A login without client_id is only taken from an issuer with one registration.
        self.found = rows[0] if len(rows) == 1 else None
        if self.found is None:
            known = self.session.scalar(select(LtiRegistration.id).where(LtiRegistration.issuer == iss).limit(1))
            self.unmatched = "client_id" if known is not None else "issuer"
            return None
        return self.library_registration(self.found)

    def library_registration(self, row: LtiRegistration) -> Registration:
        """The registration as pylti1p3 holds one, with the tool's signing key."""
        key = signing_key(session=self.session)
        return (Registration().set_issuer(row.issuer).set_client_id(row.client_id)
                .set_auth_login_url(row.auth_login_url).set_auth_token_url(row.auth_token_url)
                .set_key_set_url(row.key_set_url).set_tool_private_key(key.private_key_pem)
                .set_tool_public_key(JWK(**key.public_jwk).export_to_pem().decode()))

    def find_deployment(self, iss: str, deployment_id: str) -> Deployment | None:
        return self.find_deployment_by_params(iss, deployment_id, None)

    def find_deployment_by_params(self, iss: str, deployment_id: str, client_id: str | None, *args,
                                  **kwargs) -> Deployment | None:
        if self.found is None or self.found.issuer != iss:
            return None
        known = self.session.scalar(select(LtiDeployment).where(LtiDeployment.registration_id == self.found.id,
                                                                LtiDeployment.deployment_id == deployment_id))
        return Deployment().set_deployment_id(deployment_id) if known is not None else None


# A launch whose nonce is not this tool's, already used or expired: what its error page says of the nonce.
NONCE_REFUSED = "was not sent by this tool, or its launch was already used or has expired: start again from the LMS"


class LaunchStates(SessionService):
    """pylti1p3's session, kept in the lti_launch_states table instead of a browser session: a launch's nonce must
    be one this tool sent, with the launch's state, unused and unexpired (pylti1p3's own session only checks that a
    nonce was seen, so it would take a replayed launch). The check only reads: the launch then waits on the platform's
    key set with no transaction open (`fetch_key_set`), and `take` uses the nonce up in the launch's short write
    transaction after. The browser's state cookie is checked by pylti1p3 as well; nothing here vouches for a state
    without it."""

    def __init__(self, session: Session, state: str | None = None):  # not the base's: no framework session here
        self.session, self.state = session, state
        self.found: LtiLaunchState | None = None  # the login the nonce checked out against, not yet used up
        self.used: LtiLaunchState | None = None  # the same, once `take` used it up for this launch

    def save_nonce(self, nonce: str) -> None:
        pass  # stored with its state by `record_login`, once the login's redirect holds both

    def check_nonce(self, nonce: str) -> bool:
        row = self.session.scalar(select(LtiLaunchState).where(LtiLaunchState.nonce == nonce,
                                                               LtiLaunchState.state == (self.state or "")))
        self.found = row if row is not None and row.used_at is None and row.expires_at > utcnow() else None
        return self.found is not None

    def take(self) -> LtiLaunchState:
        """Uses up the login the nonce checked out against, for this launch only: refused (the nonce) when a launch
        racing with the same nonce took it meanwhile, or it expired while the platform's keys were fetched."""
        if self.found is None:
            raise LaunchRefused("id_token.nonce", NONCE_REFUSED)
        now = utcnow()
        # One statement: of two launches racing with one nonce, one changes the row.
        taken = self.session.execute(update(LtiLaunchState).where(LtiLaunchState.id == self.found.id,
                                                                  LtiLaunchState.used_at.is_(None),
                                                                  LtiLaunchState.expires_at > now)
                                     .values(used_at=now)).rowcount
        if taken != 1:
            raise LaunchRefused("id_token.nonce", NONCE_REFUSED)
        self.used = self.found
        self.used.used_at = now
        return self.used

    def check_state_is_valid(self, state: str, id_token_hash: str) -> bool:
        return False  # the cookie decides (pylti1p3's fallback), never an earlier launch of the same token

    def set_state_valid(self, state: str, id_token_hash: str) -> None:
        pass

    def save_launch_data(self, key: str, jwt_body) -> None:
        pass  # a launch is acted on at once; nothing is kept for later requests

    def get_launch_data(self, key: str):
        return None

    def save_state_params(self, state: str, params) -> None:
        pass

    def get_state_params(self, state: str):
        return None


# Used or expired logins are kept this long after they expire, for a look at what was refused, then deleted.
STATE_KEPT = timedelta(days=1)


def admit_login(*, address: str) -> None:
    """Counts one anonymous login from this client address (each stores a state row): past
    settings.rate_limit_lti_logins it is Refused (429) before any work, with the seconds until one frees."""
    rule = settings.rate_limit_lti_logins
    retry_after = quotas.wait_for("LTI logins", address or "unknown", rule)
    if retry_after is not None:
        raise Refused("client address", f"at most {parse(rule)} LTI logins from one address; try again in "
                                        f"{retry_after} s", retry_after, detail="too many LTI logins")


def forget_launch_states(*, session: Session, now=None) -> int:
    """Deletes the logins that expired more than STATE_KEPT ago (called at every login); how many. No commit."""
    now = now or utcnow()
    return session.execute(delete(LtiLaunchState).where(LtiLaunchState.expires_at < now - STATE_KEPT)).rowcount


def record_login(*, session: Session, registration: LtiRegistration, state: str, nonce: str) -> None:
    """Remembers the state and nonce a login sent to the platform, for the one launch that may answer it."""
    now = utcnow()
    forget_launch_states(session=session, now=now)
    session.add(LtiLaunchState(registration_id=registration.id, state=state, nonce=nonce, created_at=now,
                               expires_at=now + STATE_LIFETIME))
    session.flush()


# --- what the server fetches from a platform: through grader.core.outbound, errors in our words ----------------------

def release(session: Session) -> None:
    """Ends `session`'s transaction before a request to a platform, committing what it wrote (a launch has written
    at most the tool's first signing key by then): a platform may take its time to answer, and no transaction,
    lock (SQLite's one write lock, a PostgreSQL row's) or pooled connection may wait with it. The next use of the
    session starts a new transaction, which must re-read what a request running meanwhile could have changed."""
    session.commit()


def fetch_key_set(url: str, *, session: Session) -> dict[str, Any]:
    """The platform's JWKS at `url` (the registration's key_set_url), fetched under the outbound policy with
    `session`'s transaction ended first (`release`). Refused with the URL and the status only: the platform's body
    never reaches the error page."""
    release(session)
    try:
        response = outbound.session().get(url, headers={"Accept": "application/json"})
    except outbound.OutboundError as exc:
        raise LaunchRefused("key_set_url", str(exc)) from None
    if not response.ok:
        raise LaunchRefused("key_set_url", f"{url} answered HTTP {response.status_code}")
    try:
        keys = response.json()
    except ValueError:
        keys = None
    if not isinstance(keys, dict) or not isinstance(keys.get("keys"), list) or not all(
            isinstance(key, dict) for key in keys["keys"]):
        raise LaunchRefused("key_set_url", f"{url} answered HTTP {response.status_code} without a JSON key set "
                                           "({\"keys\": [...]})")
    return keys


def _next_page(response: requests.Response) -> str | None:
    """The Link header's rel="next" URL exactly as the platform sent it (pylti1p3 lower-cases the whole header, which
    breaks a case-sensitive cursor), resolved against the page's own URL."""
    for link in requests.utils.parse_header_links(response.headers.get("Link", "").replace("\n", " ")):
        if "next" in link.get("rel", "").lower().split() and link.get("url"):
            return urljoin(response.url, link["url"])
    return None


class _Connector(ServiceConnector):
    """pylti1p3's service connector over the guarded session (grader.core.outbound), with errors in our words (the
    library's carry the platform's body) and `next` links kept as sent. At most MAX_PAGES pages read (GETs) per
    connector; score posts are not counted."""

    def __init__(self, registration: Registration):
        super().__init__(registration, requests_session=outbound.session())
        self._pages = 0

    def get_access_token(self, scopes) -> str:
        url = self._registration.get_auth_token_url()
        try:
            return super().get_access_token(scopes)
        except LtiServiceException as exc:
            raise LtiException(f"the token request to {url} answered HTTP {exc.response.status_code}") from None
        except (ValueError, KeyError, TypeError):
            raise LtiException(f"the token request to {url} answered without a JSON access_token") from None

    def make_service_request(self, scopes, url: str, is_post: bool = False, data: str | None = None,
                             content_type: str = "application/json", accept: str = "application/json",
                             case_insensitive_headers: bool = False):
        self._pages += 0 if is_post else 1
        if self._pages > MAX_PAGES:
            raise LtiException(f"{url}: more than {MAX_PAGES} pages; stopped")
        headers = {"Authorization": "Bearer " + self.get_access_token(scopes), "Accept": accept}
        if is_post:
            headers["Content-Type"] = content_type
            response = self._requests_session.post(url, data=data or None, headers=headers)
        else:
            response = self._requests_session.get(url, headers=headers)
        if not response.ok:
            raise LtiException(f"{url} answered HTTP {response.status_code}")
        try:
            body = response.json() if response.content else None
        except ValueError:
            raise LtiException(f"{url} answered HTTP {response.status_code} without JSON") from None
        return {"headers": response.headers if case_insensitive_headers else dict(response.headers), "body": body,
                "next_page_url": _next_page(response)}


def _connector(session: Session, registration: LtiRegistration) -> _Connector:
    return _Connector(RegistrationConf(session).library_registration(registration))


# What a failed exchange with a platform may say: ours, built from the URL and the HTTP status. A library message
# that could hold the platform's body (pylti1p3 quotes it) is replaced.
_UNSAFE = re.compile(r"HTTP response \[|Must be JSON|Error during fetch URL")


def failure_text(exc: BaseException) -> str:
    """What an instructor or a page may read of a failed exchange with a platform: never the remote body."""
    if isinstance(exc, LtiServiceException):
        return f"{exc.response.url} answered HTTP {exc.response.status_code}"
    if isinstance(exc, outbound.OutboundError):
        return str(exc)
    if isinstance(exc, requests.RequestException):
        return "the platform could not be reached"
    text = str(exc)
    if isinstance(exc, KeyError):
        return f"the platform's answer lacks {text}"
    if _UNSAFE.search(text):
        return "the platform's answer was refused"
    return text[:300]


# --- what a launch means here ------------------------------------------------------------------------------------

@dataclass(frozen=True)
class Landing:
    user: User
    assignment: Assignment | None


def role_of(roles: list[str]) -> Role:
    """The course role of a launch's role claims: Instructor -> instructor, a teaching assistant -> auditor,
    Learner -> student; anything else is refused."""
    if TA_ROLE in roles:
        return Role.AUDITOR
    if any(role in INSTRUCTOR_ROLES for role in roles):
        return Role.INSTRUCTOR
    if any(role in LEARNER_ROLES for role in roles):
        return Role.STUDENT
    raise LaunchRefused("id_token.roles", f"names no role this tool knows ({', '.join(roles) or 'none'}): "
                                          "Instructor, TeachingAssistant or Learner")


def _user_name(registration: LtiRegistration, sub: str) -> str:
    # The LMS id may be long and is opaque: a stable digest of it names the user in the course.
    return "lti-" + hashlib.sha256(f"{registration.id}:{sub}".encode()).hexdigest()[:20]


def sign_in(*, session: Session, registration: LtiRegistration, claims: dict[str, Any],
            states: LaunchStates) -> Landing:
    """The user a validated resource-link launch is, created or updated in the registration's course (role, name
    and email from the claims), and the assignment its link points to (custom parameter `assignment_id`). The
    caller opens the page session and commits. The launch's login is used up first (`LaunchStates.take`), in the
    same transaction."""
    if states.found is None or states.found.registration_id != registration.id:
        raise LaunchRefused("state", "was issued for another platform's login")
    states.take()
    sub = claims.get("sub")
    if not isinstance(sub, str) or not sub or len(sub) > 255:
        raise LaunchRefused("id_token.sub", "must be the LMS user id, 1 to 255 characters")
    roles = claims.get(CLAIM + "roles")
    role = role_of(roles if isinstance(roles, list) else [])
    assignment = _linked_assignment(session, registration, claims.get(CLAIM + "custom"))
    user, _ = _person(session, registration, sub, role, claims.get("name"), claims.get("email"))
    _note_context(session, registration, claims, assignment)
    session.flush()
    session.refresh(user)
    return Landing(user=user, assignment=assignment)


def _person(session: Session, registration: LtiRegistration, sub: str, role: Role, name: Any,
            email: Any) -> tuple[User, str]:
    """The user of this LMS id, created in the registration's course or updated (role, name, email); and whether
    that was "added", "updated" or "unchanged"."""
    identity = session.scalar(select(LtiIdentity).where(LtiIdentity.registration_id == registration.id,
                                                        LtiIdentity.sub == sub))
    if identity is None:
        user = User(course_id=registration.course_id, name=_user_name(registration, sub), role=role.value)
        session.add(user)
        session.flush()
        session.add(LtiIdentity(registration_id=registration.id, sub=sub, user_id=user.id))
        change = "added"
    else:
        user, change = identity.user, "unchanged"
    before = (user.role, user.full_name, user.email)
    user.role = role.value
    if isinstance(name, str) and name.strip():
        user.full_name = name.strip()[:128]
    if isinstance(email, str) and 0 < len(email) <= 254 and "@" in email:
        user.email = email
    if change == "unchanged" and (user.role, user.full_name, user.email) != before:
        change = "updated"
    return user, change


def _linked_assignment(session: Session, registration: LtiRegistration, custom: Any) -> Assignment | None:
    value = custom.get("assignment_id") if isinstance(custom, dict) else None
    if value is None or value == "":
        return None
    try:
        assignment_id = int(value)
    except (TypeError, ValueError):
        assignment_id = None
    found = session.get(Assignment, assignment_id) if assignment_id is not None else None
    if found is None or found.course_id != registration.course_id:
        raise LaunchRefused("id_token.custom.assignment_id",
                            f"is {value!r}: no assignment of the course this platform is registered for")
    return found


# --- deep linking: an instructor picks which assignment a new LMS link opens --------------------------------------

DEEP_LINK_SETTINGS = "https://purl.imsglobal.org/spec/lti-dl/claim/deep_linking_settings"


def hold_deep_link(*, states: LaunchStates, landing: Landing, claims: dict[str, Any]) -> None:
    """Keeps a validated deep-linking launch's settings on its login row until the instructor's choice; only an
    instructor may add the tool's links."""
    if not access.is_instructor(landing.user):
        raise LaunchRefused("id_token.roles", "must name an Instructor: only instructors add this tool's links")
    settings = claims.get(DEEP_LINK_SETTINGS)
    if not isinstance(settings, dict) or not str(settings.get("deep_link_return_url", "")).startswith(("https://",
                                                                                                        "http://")):
        raise LaunchRefused("id_token.deep_linking_settings", "must give the platform's deep_link_return_url")
    states.used.deployment_id = claims.get(CLAIM + "deployment_id")
    states.used.deep_link = settings


def pending_deep_link(*, session: Session, state: str) -> LtiLaunchState:
    """The deep-linking launch of this state, unanswered and within STATE_LIFETIME of its launch; refused otherwise."""
    row = session.scalar(select(LtiLaunchState).where(LtiLaunchState.state == state))
    if row is None or row.deep_link is None or row.used_at is None or utcnow() - row.used_at > STATE_LIFETIME:
        raise LaunchRefused("state", "names no open deep-linking launch: it was answered, has expired, or never "
                                     "was; start again from the LMS")
    return row


def answer_deep_link(*, session: Session, row: LtiLaunchState, assignment_id: int,
                     launch_url: str) -> tuple[str, str]:
    """The platform's return URL and the signed LtiDeepLinkingResponse: one resource link that launches
    `assignment_id` (an assignment of the registration's course). The launch is answered once; the caller commits."""
    assignment = session.get(Assignment, assignment_id)
    if assignment is None or assignment.course_id != row.registration.course_id:
        raise LaunchRefused("assignment_id", "is no assignment of this course")
    settings = row.deep_link
    link = (DeepLinkResource().set_url(launch_url).set_title(assignment.title)
            .set_custom_params({"assignment_id": str(assignment.id)}))
    registration = RegistrationConf(session).library_registration(row.registration)
    token = DeepLink(registration, row.deployment_id, settings).get_response_jwt([link])
    row.deep_link = None
    return settings["deep_link_return_url"], token


# --- grades back (AGS): each student's counted score on a line item per assignment ---------------------------------

AGS_ENDPOINT = "https://purl.imsglobal.org/spec/lti-ags/claim/endpoint"
NRPS_CLAIM = "https://purl.imsglobal.org/spec/lti-nrps/claim/namesroleservice"
SCORE_SCOPE = "https://purl.imsglobal.org/spec/lti-ags/scope/score"
LINEITEM_SCOPE = "https://purl.imsglobal.org/spec/lti-ags/scope/lineitem"
LINEITEM_READ_SCOPE = "https://purl.imsglobal.org/spec/lti-ags/scope/lineitem.readonly"


def _service_url(value: Any) -> str | None:
    """A service URL of a launch's claims, or None when it is no absolute http(s) URL (fetched later under the
    outbound policy, which checks it again)."""
    if not isinstance(value, str) or len(value) > 2000:
        return None
    parts = urlsplit(value)
    return value if parts.scheme in ("http", "https") and parts.netloc else None


def _use_link_line_item(session: Session, context: LtiContext, assignment: Assignment, url: str) -> None:
    """The launch's link has its own gradebook column (the AGS claim's `lineitem`): the assignment's scores in this
    LMS course go there, not to a column the tool would create. A column known before under another URL forgets
    what was sent to it, so every score is sent to the link's column."""
    item = session.scalar(select(LtiLineItem).where(LtiLineItem.context_id == context.id,
                                                    LtiLineItem.assignment_id == assignment.id))
    if item is not None and item.url == url:
        return
    if item is None:
        session.add(LtiLineItem(context_id=context.id, assignment_id=assignment.id, url=url))
    else:
        session.execute(delete(LtiScore).where(LtiScore.line_item_id == item.id))
        item.url = url
    session.flush()
    scores_changed(session=session, assignment=assignment)


def _note_context(session: Session, registration: LtiRegistration, claims: dict[str, Any],
                  assignment: Assignment | None = None) -> None:
    """Keeps the launch's LMS course and its grades service endpoint (the latest launch's word counts), and the
    link's own line item for the assignment it opens."""
    context = claims.get(CLAIM + "context")
    context_id = context.get("id") if isinstance(context, dict) else None
    if not isinstance(context_id, str) or not 0 < len(context_id) <= 255:
        return
    endpoint = claims.get(AGS_ENDPOINT) if isinstance(claims.get(AGS_ENDPOINT), dict) else {}
    lineitems = _service_url(endpoint.get("lineitems"))
    lineitem = _service_url(endpoint.get("lineitem"))
    scopes = [x for x in endpoint.get("scope", []) if isinstance(x, str)] if isinstance(endpoint.get("scope"),
                                                                                        list) else []
    row = session.scalar(select(LtiContext).where(LtiContext.registration_id == registration.id,
                                                  LtiContext.context_id == context_id))
    if row is None:
        row = LtiContext(registration_id=registration.id, context_id=context_id)
        session.add(row)
    if lineitems or lineitem:  # a launch without the claim (a placement without grades) leaves the known alone
        row.scopes = scopes
    if lineitems:
        first = row.lineitems_url is None
        row.lineitems_url = lineitems
        if first:  # a new gradebook gets the scores graded before it was known
            session.flush()
            scores_changed(session=session, course=registration.course)
    if lineitem and assignment is not None:
        session.flush()
        _use_link_line_item(session, row, assignment, lineitem)
    roster = claims.get(NRPS_CLAIM)
    if isinstance(roster, dict) and _service_url(roster.get("context_memberships_url")):
        row.memberships_url = roster["context_memberships_url"]
    row.updated_at = utcnow()


@dataclass(frozen=True)
class ScoreSent:
    student: str
    context: str
    status: str  # sent | unchanged | failed | withheld
    score: float | None = None
    error: str | None = None


@dataclass(frozen=True)
class _Due:
    """One LMS student's counted score, as read before any request leaves: plain values, so that nothing of the
    session is used while a platform answers."""

    user_id: int
    student: str
    sub: str
    submission_id: int
    score: float
    maximum: float
    comment: str
    unchanged: bool  # the last score sent on the known line item is this one, of this attempt


@dataclass(frozen=True)
class _Gradebook:
    """One LMS course's part of a send, as read before any request leaves."""

    context_id: int
    name: str  # the LMS course's id
    withheld: list[ScoreSent]
    due: list[_Due]
    registration: Registration | None = None  # pylti1p3's, with the tool's signing key (None: nothing due)
    service: dict[str, Any] | None = None  # the grades service's endpoint and the scopes a token asks for
    item_url: str | None = None  # the assignment's line item there, if known


def send_scores(*, session: Session, assignment: Assignment, report_url: str = "") -> list[ScoreSent]:
    """Sends each LMS student's counted score for `assignment` to every LMS course of its registrations that gave a
    grades service: on the assignment's line item there (created once, then reused), only where the score or its
    attempt changed since the last send or that send failed. A student with any item still withheld from them gets
    no score (it would tell the hidden items). `report_url` is the report's URL with `{id}` for the submission.

    What is due is read first and the transaction ended (`release`): no transaction, lock or pooled connection waits
    on a platform. Each LMS course's outcome is then stored in a short transaction of its own, which reads its line
    item again (`_record_scores`). Failures are stored with their error and tried again on the next call. Commits."""
    assignment_id, title = assignment.id, assignment.title
    gradebooks = _gradebooks(session, assignment, report_url)
    release(session)
    out: list[ScoreSent] = []
    for book in gradebooks:
        url, results = _post_scores(book, assignment_id, title) if book.due else (None, [])
        _record_scores(session, book, assignment_id, url, results)
        session.commit()
        out += book.withheld + [ScoreSent(due.student, book.name, status, due.score, error)
                                for due, status, error in results]
    return out


def _gradebooks(session: Session, assignment: Assignment, report_url: str) -> list[_Gradebook]:
    """What `send_scores` sends, per LMS course: read in the caller's transaction, before any request leaves."""
    counted = {c.submission.student_id: c for c in counted_grades(session=session, assignment=assignment)}
    link_items = select(LtiLineItem.context_id).where(LtiLineItem.assignment_id == assignment.id)
    contexts = list(session.scalars(select(LtiContext).join(LtiRegistration)
                                    .where(LtiRegistration.course_id == assignment.course_id,
                                           LtiContext.lineitems_url.is_not(None) | LtiContext.id.in_(link_items))
                                    .order_by(LtiContext.id)))
    books = []
    for context in contexts:
        item = session.scalar(select(LtiLineItem).where(LtiLineItem.context_id == context.id,
                                                        LtiLineItem.assignment_id == assignment.id))
        people = session.scalars(select(LtiIdentity).where(LtiIdentity.registration_id == context.registration_id)
                                 .order_by(LtiIdentity.id))
        withheld, due = [], []
        for identity in people:
            c = counted.get(identity.user_id)
            if c is None or not access.is_student(identity.user):
                continue
            if grade_view(session=session, submission=c.submission, user=identity.user, report=False).hidden:
                withheld.append(ScoreSent(identity.user.name, context.context_id, "withheld"))
                continue
            prior = None if item is None else session.scalar(
                select(LtiScore).where(LtiScore.line_item_id == item.id, LtiScore.user_id == identity.user_id))
            unchanged = (prior is not None and prior.status == "sent" and prior.score_given == c.counted
                         and prior.score_maximum == c.max_total and prior.submission_id == c.submission.id)
            comment = f"attempt {c.submission.attempt}" + (
                f": {report_url.format(id=c.submission.id)}" if report_url else "")
            due.append(_Due(identity.user_id, identity.user.name, identity.sub, c.submission.id, c.counted,
                            c.max_total, comment, unchanged))
        if not due:
            books.append(_Gradebook(context.id, context.context_id, withheld, due))
            continue
        service = {"scope": token_scopes(context.scopes or [], line_item_known=item is not None),
                   "lineitems": context.lineitems_url}
        books.append(_Gradebook(context.id, context.context_id, withheld, due,
                                RegistrationConf(session).library_registration(context.registration), service,
                                item.url if item is not None else None))
    return books


def token_scopes(offered: list[str], *, line_item_known: bool) -> list[str]:
    """The AGS scopes a token is asked for: only what the tool uses of what the platform offered. Scores always; the
    line item scope only while the assignment's column must still be found or created (read-only where that is all
    that is offered); never results, which the tool does not read."""
    wanted = [SCORE_SCOPE]
    if not line_item_known:
        wanted.append(LINEITEM_SCOPE if LINEITEM_SCOPE in offered else LINEITEM_READ_SCOPE)
    return [scope for scope in wanted if scope in offered]


# One student's outcome of a send: what was due, its status (sent | unchanged | failed) and the error.
_Outcome = tuple[_Due, str, str | None]


def _post_scores(book: _Gradebook, assignment_id: int, title: str) -> tuple[str | None, list[_Outcome]]:
    """Posts one LMS course's changed scores (the token, the line item found or made, each score): no database here,
    only what `_gradebooks` read. The line item's URL the scores went to (None: none was found or made), and each
    student's status and error."""
    ags = AssignmentsGradesService(_Connector(book.registration), book.service)
    url, unreachable, results = book.item_url, None, []
    for due in book.due:
        if due.unchanged:
            results.append((due, "unchanged", None))
            continue
        try:
            if unreachable is not None:  # one timeout per pass, not one per student: the rest wait for the retry
                raise unreachable
            if url is None:
                url = ags.find_or_create_lineitem(
                    LineItem().set_tag(f"grader-assignment-{assignment_id}").set_resource_id(str(assignment_id))
                    .set_label(title).set_score_maximum(due.maximum)).get_id()
                if not url:
                    raise LtiException(f"{book.service['lineitems']} answered a line item without an id")
            ags.put_grade(LibraryGrade().set_score_given(due.score).set_score_maximum(due.maximum)
                          .set_timestamp(utcnow().isoformat() + "Z").set_activity_progress("Completed")
                          .set_grading_progress("FullyGraded").set_user_id(due.sub).set_comment(due.comment),
                          LineItem().set_id(url))
            status, error = "sent", None
        except (LtiException, requests.RequestException, AttributeError, KeyError, TypeError, ValueError) as exc:
            status, error = "failed", failure_text(exc)[:1000]
            if isinstance(exc, requests.RequestException):
                unreachable = exc
        results.append((due, status, error))
    return url, results


def _record_scores(session: Session, book: _Gradebook, assignment_id: int, url: str | None,
                   results: list[_Outcome]) -> None:
    """Stores one LMS course's outcome in a new transaction (the caller commits): the line item this send found or
    made, and each score sent or failed on it. Read again, not taken from before the requests: where a launch named
    another column for the assignment meanwhile, nothing is stored for the old one (the launch marked the scores
    changed, so the next pass sends them to the new one)."""
    if url is None:
        return  # no line item yet: nothing to hold a failure; the next call tries again
    fresh = {"populate_existing": True}  # the rows as they are now, not as the session saw them before the requests
    item = session.scalar(select(LtiLineItem).where(LtiLineItem.context_id == book.context_id,
                                                    LtiLineItem.assignment_id == assignment_id)
                          .execution_options(**fresh))
    if item is None:
        item = LtiLineItem(context_id=book.context_id, assignment_id=assignment_id, url=url)
        session.add(item)
        session.flush()
    elif item.url != url:
        return
    now = utcnow()
    for due, status, error in results:
        if status == "unchanged":
            continue
        row = session.scalar(select(LtiScore).where(LtiScore.line_item_id == item.id, LtiScore.user_id == due.user_id)
                             .execution_options(**fresh)) or LtiScore(line_item_id=item.id, user_id=due.user_id,
                                                                      tries=0)
        row.submission_id, row.score_given, row.score_maximum = due.submission_id, due.score, due.maximum
        row.status, row.error, row.tries, row.sent_at = status, error, (row.tries or 0) + 1, now
        session.add(row)
    session.flush()

