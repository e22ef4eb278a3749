"""The language switch on every page: POST /language keeps the reader's choice in a cookie that wins over the
browser's Accept-Language (grader.i18n.choose), then goes back to the page it came from. Origin-checked like every
page form (grader.pages.csrf, on the pages' router)."""

from __future__ import annotations

from fastapi import APIRouter, Form, status
from fastapi.responses import RedirectResponse

from grader import i18n
from grader.services.errors import Invalid

router = APIRouter(include_in_schema=False)
# A year: a language is a lasting preference, not a sign-in.
COOKIE_MAX_AGE_S = 365 * 86400


def _back(target: str) -> str:
    """Only a path on this site: never an open redirect to another host."""
    return target if target.startswith("/") and not target.startswith("//") and "\\" not in target else "/submissions"


@router.post("/language")
def switch_language(locale: str = Form(""), next: str = Form("/submissions")):
    """Shows every page in `locale` (en or zh) from now on in this browser."""
    if locale not in i18n.LOCALES:
        raise Invalid("unknown language", [{"field": "locale", "rule": f"must be one of {', '.join(i18n.LOCALES)}"}])
    response = RedirectResponse(_back(next), status_code=status.HTTP_303_SEE_OTHER)
    response.set_cookie(i18n.COOKIE, locale, max_age=COOKIE_MAX_AGE_S, httponly=True, samesite="lax", path="/")
    return response
