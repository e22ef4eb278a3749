"""How a page answers a refusal (installed by grader.main through grader.web.errors, the one place errors become
answers): nobody signed in -> the sign-in form, coming back here after; a thing the caller may not see or act on
(NotFound, Forbidden) -> the not-found page, revealing nothing; any other domain error -> the error page with the
rule it broke. The API under /v1 answers the same errors as JSON."""

from __future__ import annotations

from urllib.parse import quote

from fastapi import FastAPI, Request, status
from fastapi.responses import HTMLResponse, RedirectResponse, Response

from grader.core.db import new_session
from grader.i18n import N_
from grader.pages.auth import SignInRequired, page_user
from grader.pages.csrf import CrossSiteRefused
from grader.pages.templates import TEMPLATES
from grader.services.errors import DomainError, Forbidden, NotFound


# The request fields a refusal names, as a reader knows them (the API names them as they are sent).
FIELD_LABELS = {"assignment_id": N_("assignment"), "sheet": N_("prediction sheet"), "client address": N_("your address"),
                "token": N_("API token"), "file": N_("file")}


def sign_in_redirect(request: Request) -> RedirectResponse:
    target = request.url.path + (f"?{request.url.query}" if request.url.query else "")
    return RedirectResponse(f"/sign-in?next={quote(target)}", status_code=status.HTTP_303_SEE_OTHER)


def not_found(request: Request, user, what: str) -> HTMLResponse:
    return TEMPLATES.TemplateResponse(request, "not_found.html", {"user": user, "what": what},
                                      status_code=status.HTTP_404_NOT_FOUND)


def page_error(request: Request, exc: DomainError, code: int) -> Response:
    with new_session() as session:
        user = page_user(request, session)
        if isinstance(exc, NotFound | Forbidden):
            return not_found(request, user, exc.detail.removesuffix(" not found"))
        return TEMPLATES.TemplateResponse(request, "error.html", {"user": user, "error": exc, "code": code,
                                                                  "field_labels": FIELD_LABELS},
                                          status_code=code)


async def _sign_in(request: Request, exc: SignInRequired) -> Response:
    return Response(status_code=status.HTTP_401_UNAUTHORIZED) if exc.fetched else sign_in_redirect(request)


async def _cross_site(request: Request, exc: CrossSiteRefused) -> Response:
    return page_error(request, exc, status.HTTP_403_FORBIDDEN)


def install(app: FastAPI) -> None:
    app.add_exception_handler(SignInRequired, _sign_in)
    app.add_exception_handler(CrossSiteRefused, _cross_site)
