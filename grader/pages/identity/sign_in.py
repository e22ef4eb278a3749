"""Signing in with a token and out: the sign-in form, the page session it opens (grader.services.identity.sessions),
and the home page's redirect. A student's single-use link is grader.pages.identity.sign_in_links."""

from __future__ import annotations

from fastapi import APIRouter, Form, Request, status
from fastapi.responses import HTMLResponse, RedirectResponse

from grader.core.settings import settings
from grader.pages.auth import COOKIE, PageUser, SignedIn, clear_session_cookie, set_session_cookie
from grader.pages.templates import TEMPLATES
from grader.services.identity import accounts, sessions
from grader.web.deps import SessionDep

router = APIRouter(include_in_schema=False)


@router.get("/", response_class=HTMLResponse)
def home(user: SignedIn):
    return RedirectResponse("/submissions", status_code=status.HTTP_303_SEE_OTHER)


def _sign_in_page(request: Request, user, next: str, error: str | None = None, code: int = status.HTTP_200_OK):
    return TEMPLATES.TemplateResponse(request, "identity/sign_in.html", {
        "user": user, "next": _safe_next(next), "error": error, "idle_hours": round(settings.session_idle_s / 3600),
        "lifetime_days": round(settings.session_lifetime_s / 86400)}, status_code=code)


@router.get("/sign-in", response_class=HTMLResponse)
def sign_in_form(request: Request, user: PageUser, next: str = "/submissions"):
    return _sign_in_page(request, user, next)


@router.post("/sign-in", response_class=HTMLResponse)
def sign_in(request: Request, session: SessionDep, token: str = Form(""), next: str = Form("/submissions")):
    """Opens a page session for a working token; the cookie gets the session's secret, never the token. Wrong tokens
    are counted per client address, and past settings.rate_limit_sign_in_failures refused (429) before any look-up."""
    address = request.client.host if request.client else "unknown"
    sessions.refuse_failing_address(address)
    row = accounts.find_token(session=session, token=token.strip())
    refusal = accounts.token_refusal(row)
    if refusal is not None:
        sessions.count_failed_sign_in(address)
        error = "That token is unknown or has been revoked." if row is None else f"That {refusal}."
        return _sign_in_page(request, None, next, error, status.HTTP_401_UNAUTHORIZED)
    if request.cookies.get(COOKIE):  # a session this browser held before ends with the new one
        sessions.revoke_session(session=session, secret=request.cookies[COOKIE])
    secret = sessions.open_session(session=session, user=row.user, token=row)
    session.commit()
    response = RedirectResponse(_safe_next(next), status_code=status.HTTP_303_SEE_OTHER)
    set_session_cookie(response, request, secret)
    return response


@router.post("/sign-out")
def sign_out(request: Request, session: SessionDep):
    """Revokes the session: the same cookie, kept or copied, no longer opens a page."""
    if request.cookies.get(COOKIE):
        sessions.revoke_session(session=session, secret=request.cookies[COOKIE])
        session.commit()
    response = RedirectResponse("/sign-in", status_code=status.HTTP_303_SEE_OTHER)
    clear_session_cookie(response)
    return response


def _safe_next(target: str) -> str:
    """Only a path on this site: never an open redirect to another host."""
    return target if target.startswith("/") and not target.startswith("//") else "/submissions"
