"""A sign-in link used by a program rather than a browser (the notebook client, issue 48): the link works once, as on
its page, and the program gets an API token of its own instead of a page session."""

from __future__ import annotations

from fastapi import APIRouter, HTTPException, Path, Request, status
from pydantic import BaseModel

from grader.api.responses import errors
from grader.services.identity import accounts, sessions, sign_in_links
from grader.web.deps import SessionDep

router = APIRouter(tags=["sign-in"])
# As long as the longest page session a link opens (settings.session_lifetime_s, 7 days): the link gives no more.
TOKEN_DAYS = 7


class LinkToken(BaseModel):
    token: str
    user: str
    course: str
    expires_in_days: int


@router.post("/sign-in-links/{secret}/token", response_model=LinkToken, responses=errors(404, 422, 429, _404=(
    "An unknown link, or one used, expired or replaced; the detail says which")))
def token_for_link(request: Request, secret: str = Path(min_length=1, max_length=128), *, session: SessionDep):
    """Use a student's sign-in link (once, as pressing its page's button does) and get an API token for the
    notebook client, valid for 7 days; the link then no longer works. Unknown look-ups count against the address."""
    address = request.client.host if request.client else "unknown"
    used = sign_in_links.redeem(session=session, secret=secret, address=address)
    if used.refusal is not None:
        raise HTTPException(status.HTTP_404_NOT_FOUND, used.refusal)
    sessions.revoke_session(session=session, secret=used.session_secret)  # no page is signed in by this use
    token = accounts.create_token(session=session, user=used.user, expires_in_days=TOKEN_DAYS)
    session.commit()
    return LinkToken(token=token, user=used.user.name, course=used.user.course.name, expires_in_days=TOKEN_DAYS)
