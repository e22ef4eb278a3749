"""Who is looking at a page: the session cookie set at sign-in, or the API's `Authorization: Bearer` header.

The cookie holds the caller's API token (HttpOnly, SameSite=Strict, Secure outside development): the pages and
the API share one credential and one revocation. The API itself accepts only the header, so a page can never be
used to submit on a student's behalf from another site.
"""

from __future__ import annotations

from typing import Annotated

from fastapi import Depends, Request

from grader import crud
from grader.api.deps import SessionDep
from grader.models import User
from grader.settings import settings

COOKIE = "grader_session"
COOKIE_MAX_AGE_S = 12 * 3600


def page_user(request: Request, session: SessionDep) -> User | None:
    """The signed-in user, or None (the page then redirects to the sign-in form)."""
    header = request.headers.get("authorization", "")
    scheme, _, token = header.partition(" ")
    if scheme.lower() != "bearer" or not token:
        token = request.cookies.get(COOKIE, "")
    return crud.user_by_token(session=session, token=token.strip()) if token else None


PageUser = Annotated[User | None, Depends(page_user)]


def set_session_cookie(response, token: str) -> None:
    response.set_cookie(COOKIE, token, max_age=COOKIE_MAX_AGE_S, httponly=True, samesite="strict",
                        secure=settings.environment == "production", path="/")


def clear_session_cookie(response) -> None:
    response.delete_cookie(COOKIE, path="/")
