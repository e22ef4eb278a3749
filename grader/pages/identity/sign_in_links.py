"""A student's sign-in link: GET shows a confirmation with one button (mail clients' link scanners follow GETs and
must not use up the link), POST uses the link once and opens the same page session the sign-in form opens. Both
count a look-up of an unknown link against the client's address (grader.services.identity.sign_in_links.look_up): past the
quota, the refusal page with Retry-After (429)."""

from __future__ import annotations

from fastapi import APIRouter, Request, status
from fastapi.responses import HTMLResponse, RedirectResponse

from grader.web.deps import SessionDep
from grader.pages.auth import COOKIE, PageUser, set_session_cookie
from grader.pages.templates import TEMPLATES
from grader.services.identity import sessions, sign_in_links

router = APIRouter(include_in_schema=False)


def _page(request: Request, user, link, refusal: str | None, code: int = status.HTTP_200_OK):
    return TEMPLATES.TemplateResponse(request, "identity/sign_in_link.html", {
        "user": user, "link": link, "refusal": refusal, "action": request.url.path}, status_code=code)


def client_address(request: Request) -> str:
    """The client's address (behind a trusted proxy, from its X-Forwarded-For: grader.web.admission.TrustedProxies)."""
    return request.client.host if request.client else "unknown"


def _refused_code(link) -> int:
    # 404 for a link never issued; 410 for one that existed and no longer works.
    return status.HTTP_404_NOT_FOUND if link is None else status.HTTP_410_GONE


@router.get("/sign-in/link/{secret}", response_class=HTMLResponse)
def confirm(request: Request, secret: str, session: SessionDep, user: PageUser):
    """Says whom the link signs in and asks for one press; nothing is used up here."""
    link = sign_in_links.look_up(session=session, secret=secret, address=client_address(request))
    refusal = sign_in_links.refusal(link)
    return _page(request, user, link, refusal, _refused_code(link) if refusal else status.HTTP_200_OK)


@router.post("/sign-in/link/{secret}", response_class=HTMLResponse)
def use(request: Request, secret: str, session: SessionDep, user: PageUser):
    """Uses the link (once) and signs this browser in: the cookie gets a new session's secret, never the link's."""
    used = sign_in_links.redeem(session=session, secret=secret, address=client_address(request))
    if used.refusal is not None:
        link = sign_in_links.find(session=session, secret=secret)
        return _page(request, user, link, used.refusal, _refused_code(link))
    if request.cookies.get(COOKIE):  # a session this browser held before ends with the new one
        sessions.revoke_session(session=session, secret=request.cookies[COOKIE])
    course = used.user.course.name
    session.commit()
    response = RedirectResponse(f"/courses/{course}", status_code=status.HTTP_303_SEE_OTHER)
    set_session_cookie(response, request, used.session_secret)
    return response
