"""The LTI 1.3 tool's doors: `/lti/login` (OIDC login initiation), `/lti/launch` (the platform's signed id_token)
and `/lti/jwks` (the tool's public keys), with the thin adapter pylti1p3 needs for FastAPI (its Flask and Django
adapters show the shape: a request, a cookie service, a redirect).

This router is mounted by grader.main outside the pages' origin check (grader.pages.csrf): a launch is a cross-site
form POST from the LMS by design. It is authenticated instead by the id_token's signature against the platform's
JWKS, its one-time nonce and the state cookie this browser got at login (grader.services.lti.launch).

The state cookie must reach a cross-site POST, so over https it is SameSite=None; Secure. Over plain http (tests on
loopback, local trials) it is sent without those, which a browser will not send cross-site: deploy behind https.
"""

from __future__ import annotations

from urllib.parse import parse_qs, quote, urlsplit

from fastapi import APIRouter, Depends, Form, Request, status
from fastapi.responses import HTMLResponse, RedirectResponse, Response
from pylti1p3.cookie import CookieService
from pylti1p3.exception import LtiException, OIDCException
from pylti1p3.message_launch import MessageLaunch
from pylti1p3.oidc_login import OIDCLogin
from pylti1p3.redirect import Redirect
from pylti1p3.request import Request as LtiRequest

from grader.web.deps import SessionDep
from grader.core import outbound
from grader.pages.auth import COOKIE, set_session_cookie
from grader.pages.csrf import same_origin
from grader.pages.templates import TEMPLATES
from grader.services.setup import assignments
from grader.services.lti import launch as lti
from grader.services.identity import sessions
from grader.services.lti.launch import LaunchRefused
from grader.services.identity import access

router = APIRouter(prefix="/lti", include_in_schema=False)

STATE_COOKIE_PREFIX = "lti1p3-"


class _Params(LtiRequest):
    """What pylti1p3 reads of a request: its parameters and cookies, and whether it came over https."""

    def __init__(self, request: Request, params: dict[str, str]):
        self.request, self.params = request, params

    @property
    def session(self):
        return None

    def is_secure(self) -> bool:
        return self.request.url.scheme == "https"

    def get_param(self, key: str):
        return self.params.get(key)


class _Cookies(CookieService):
    """pylti1p3's cookies, collected and set on the response."""

    def __init__(self, request: Request):
        self.request, self.to_set = request, {}

    def get_cookie(self, name: str):
        return self.request.cookies.get(STATE_COOKIE_PREFIX + name)

    def set_cookie(self, name: str, value, exp: int | None = 3600):
        self.to_set[STATE_COOKIE_PREFIX + name] = (str(value), exp)

    def apply(self, response: Response) -> Response:
        secure = self.request.url.scheme == "https"
        for key, (value, exp) in self.to_set.items():
            response.set_cookie(key, value, max_age=exp, httponly=True, path="/lti/",
                                secure=secure, samesite="none" if secure else "lax")
        return response


class _Redirect(Redirect):
    def __init__(self, location: str, cookies: _Cookies):
        self.location, self.cookies = location, cookies

    def do_redirect(self) -> Response:
        return self.cookies.apply(RedirectResponse(self.location, status_code=status.HTTP_302_FOUND))

    def do_js_redirect(self) -> Response:
        return self.do_redirect()  # no inline script under this site's CSP

    def set_redirect_url(self, location: str) -> None:
        self.location = location

    def get_redirect_url(self) -> str:
        return self.location


class _Login(OIDCLogin):
    def get_redirect(self, url: str) -> _Redirect:
        return _Redirect(url, self._cookie_service)


class _Launch(MessageLaunch):
    def _get_request_param(self, key: str):
        return self._request.get_param(key)

    def fetch_public_key(self, key_set_url: str):
        # Ours, not the library's: under the outbound policy, refused without the platform's body, and with the
        # launch's transaction ended first (the nonce is used up after, in sign_in's).
        return lti.fetch_key_set(key_set_url, session=self._tool_config.session)


# pylti1p3's messages, by what they are about: the error page names that part of the launch.
_FIELDS = (("Missing state", "state"), ("State not found", "state"), ('"nonce" is empty', "id_token.nonce"),
           ("Invalid Nonce", "id_token.nonce"), ("Registration not found", "id_token.iss"),
           ("Client id not registered", "id_token.aud"), ("Unable to find deployment", "id_token.deployment_id"),
           ("deployment_id is not set", "id_token.deployment_id"), ("Signature has expired", "id_token.exp"),
           ('"exp" claim', "id_token.exp"), ('"iat" claim', "id_token.iat"),
           ("Could not find issuer", "iss"), ("Could not find login hint", "login_hint"),
           ("Could not find registration", "iss"))
_RULES = {"Invalid Nonce": lti.NONCE_REFUSED,
          "State not found": "does not match this browser's login: start again from the LMS (the tool must be "
                             "served over https for the state cookie to reach it)"}


def _refused(exc: Exception, conf: lti.RegistrationConf) -> LaunchRefused:
    message = str(exc)
    field = next((f for start, f in _FIELDS if start in message), "id_token")
    if conf.unmatched == "client_id":  # the issuer is registered, not for this client id
        field = "id_token.aud" if field == "id_token.iss" else "client_id" if field == "iss" else field
    # Never the library's words where they may quote what a platform answered: ours, with the URL and status only.
    rule = next((r for start, r in _RULES.items() if start in message), None) or lti.failure_text(exc)
    return LaunchRefused(field, rule)


@router.api_route("/login", methods=["GET", "POST"])
def login(request: Request, session: SessionDep, iss: str | None = Form(None), login_hint: str | None = Form(None),
          target_link_uri: str | None = Form(None), lti_message_hint: str | None = Form(None),
          client_id: str | None = Form(None), lti_deployment_id: str | None = Form(None)):
    """OIDC login initiation (GET or POST from the platform): sends the browser to the platform's authorization
    endpoint with a fresh state (also set as a cookie) and nonce, and the tool's own launch URL."""
    lti.admit_login(address=request.client.host if request.client else "")
    form = {"iss": iss, "login_hint": login_hint, "target_link_uri": target_link_uri,
            "lti_message_hint": lti_message_hint, "client_id": client_id, "lti_deployment_id": lti_deployment_id}
    params = dict(request.query_params) | {k: v for k, v in form.items() if v is not None}
    conf, cookies = lti.RegistrationConf(session), _Cookies(request)
    oidc = _Login(_Params(request, params), conf, lti.LaunchStates(session), cookies)
    try:
        redirect = oidc.get_redirect_object(str(request.url_for("lti_launch")))
    except (OIDCException, LtiException) as exc:
        raise _refused(exc, conf) from exc
    query = parse_qs(urlsplit(redirect.get_redirect_url()).query)
    lti.record_login(session=session, registration=conf.found, state=query["state"][0], nonce=query["nonce"][0])
    session.commit()
    return redirect.do_redirect()


@router.post("/launch", name="lti_launch", response_class=HTMLResponse)
def launch(request: Request, session: SessionDep, id_token: str = Form(""), state: str = Form("")):
    """The platform's launch (a cross-site form POST): validated by pylti1p3 (state cookie, signature against the
    platform's JWKS, issuer, audience, expiry, one-time nonce, deployment id), it signs the person into the
    registration's course and lands on the assignment the link points to."""
    params = {"id_token": id_token, "state": state}
    conf, cookies, states = lti.RegistrationConf(session), _Cookies(request), lti.LaunchStates(session, state)
    message = _Launch(_Params(request, params), conf, states, cookies, requests_session=outbound.session())
    # pylti1p3 checks the audience by registration; a token must also say when it ends.
    message.set_jwt_verify_options({"verify_aud": False, "require": ["exp", "iat"]})
    try:
        message.validate()
    except LaunchRefused:  # the platform's key set, refused by lti.fetch_key_set
        session.rollback()
        raise
    except (LtiException, KeyError, TypeError, ValueError) as exc:  # the latter: a platform's malformed keys or claims
        session.rollback()
        raise _refused(exc, conf) from None
    deep_linking = message.is_deep_link_launch()
    if not (deep_linking or message.is_resource_launch()):
        session.rollback()
        raise LaunchRefused("id_token.message_type", "must be LtiResourceLinkRequest or LtiDeepLinkingRequest")
    claims = message.get_launch_data()
    try:
        landing = lti.sign_in(session=session, registration=conf.found, claims=claims, states=states)
        if deep_linking:
            lti.hold_deep_link(states=states, landing=landing, claims=claims)
    except LaunchRefused:
        session.rollback()
        raise
    if request.cookies.get(COOKIE):  # a session this browser held before ends with the new one
        sessions.revoke_session(session=session, secret=request.cookies[COOKIE])
    secret = sessions.open_session(session=session, user=landing.user)
    session.commit()
    if deep_linking:
        response = _deep_link_page(request, session, landing.user, state)
    else:
        # A page, not a redirect: the session cookie is SameSite=Strict, and a redirect that a cross-site POST
        # started would arrive without it; this page's own navigation is same-site.
        response = TEMPLATES.TemplateResponse(request, "lti/launched.html",
                                              {"user": landing.user, "target": _landing_url(landing)})
    set_session_cookie(response, request, secret)
    response.delete_cookie(STATE_COOKIE_PREFIX + state, path="/lti/")
    return response


def _landing_url(landing: lti.Landing) -> str:
    user, assignment = landing.user, landing.assignment
    course = quote(user.course.name, safe="")
    if access.is_staff(user):
        return f"/assignments/{assignment.id}" if assignment is not None and access.is_instructor(user) \
            else f"/courses/{course}/dashboard"
    return f"/courses/{course}" + (f"#assignment-{assignment.id}" if assignment is not None else "")


def _platform_policy(url: str) -> str:
    """This site's page policy, but framed by the platform and posting back to it (its deep-linking dialog)."""
    parts = urlsplit(url)
    origin = f"{parts.scheme}://{parts.netloc}"
    return (f"default-src 'self'; object-src 'none'; base-uri 'none'; form-action 'self' {origin}; "
            f"frame-ancestors 'self' {origin}")


def _deep_link_page(request: Request, session, user, state: str) -> Response:
    row = lti.pending_deep_link(session=session, state=state)
    response = TEMPLATES.TemplateResponse(request, "lti/deep_link.html", {
        "user": user, "state": state, "assignments": assignments.of_course(session=session, course=user.course)})
    response.headers["Content-Security-Policy"] = _platform_policy(row.deep_link["deep_link_return_url"])
    return response


@router.post("/deep-link", response_class=HTMLResponse, dependencies=[Depends(same_origin)])
def deep_link(request: Request, session: SessionDep, state: str = Form(""), assignment_id: int = Form(0)):
    """The instructor's choice on the deep-linking page (a form of this site, so origin-checked): answers the
    platform with a signed LtiDeepLinkingResponse holding one link to that assignment. The launch's state is the
    capability (the page may sit in the LMS's frame, where the session cookie is not sent); it is answered once."""
    row = lti.pending_deep_link(session=session, state=state)
    return_url, token = lti.answer_deep_link(session=session, row=row, assignment_id=assignment_id,
                                             launch_url=str(request.url_for("lti_launch")))
    session.commit()
    response = TEMPLATES.TemplateResponse(request, "lti/deep_link_return.html", {
        "user": None, "return_url": return_url, "token": token})
    response.headers["Content-Security-Policy"] = _platform_policy(return_url)
    return response


@router.get("/jwks")
def jwks(session: SessionDep) -> dict:
    """The tool's public keys (JWKS): the signing key and those retired recently."""
    keys = lti.public_jwks(session=session)
    session.commit()  # the first key, made on first use
    return keys
