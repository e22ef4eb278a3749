"""Who is looking at a page: a server-side sign-in session named by the cookie, or the API's `Authorization: Bearer`
header.

Signing in with a token opens a session (grader.services.identity.sessions); the cookie holds only that session's random
secret (HttpOnly, SameSite=Strict, Secure over https and in production), never the token. It stops working when the
session is idle too long, reaches its lifetime, or is revoked by sign-out or by revoking its token. The API accepts
only the header, so a page can never be used to submit on a student's behalf from another site; the pages' own
forms are checked by origin (grader.pages.csrf).
"""

from __future__ import annotations

from typing import Annotated

from fastapi import Depends, Request

from grader.services.identity import access, accounts, sessions
from grader.services.setup import assignments
from grader.web import fresh
from grader.web.deps import SessionDep
from grader.core.models import Assignment, Course, User
from grader.services.errors import Forbidden, NotFound
from grader.core.settings import settings

COOKIE = "grader_session"


def page_user(request: Request, session: SessionDep) -> User | None:
    """The signed-in user, or None (the page then redirects to the sign-in form)."""
    header = request.headers.get("authorization", "")
    scheme, _, token = header.partition(" ")
    if scheme.lower() == "bearer" and token.strip():
        row = accounts.find_token(session=session, token=token.strip())
        if accounts.token_refusal(row) is not None:
            return None
        fresh.credential_until(request, row.expires_at)
        return row.user
    secret = request.cookies.get(COOKIE, "")
    seen = sessions.seen_session(session=session, secret=secret) if secret else None
    if session.dirty:  # the session was seen: its idle time starts again
        session.commit()
    if seen is None:
        return None
    # Until the next read would note it seen again: a 304 from memory skips no renewal a full read would make.
    fresh.credential_until(request, sessions.unchanged_until(seen))
    return seen.user


PageUser = Annotated[User | None, Depends(page_user)]


def set_session_cookie(response, request: Request, secret: str) -> None:
    response.set_cookie(COOKIE, secret, max_age=int(settings.session_lifetime_s), httponly=True, samesite="strict",
                        secure=request.url.scheme == "https" or settings.environment == "production", path="/")


def clear_session_cookie(response) -> None:
    response.delete_cookie(COOKIE, path="/")


class SignInRequired(Exception):
    """Nobody is signed in: a page answers with a redirect to the sign-in form, what a page's script fetches (a
    chart, the charts' series) with a bare 401 (grader.pages.errors)."""

    def __init__(self, *, fetched: bool = False):
        super().__init__("sign in first")
        self.fetched = fetched


def signed_in(user: PageUser) -> User:
    """The one way a page requires a user: declare `user: SignedIn` (or a role's dependency below built on it)."""
    if user is None:
        raise SignInRequired()
    return user


def signed_in_fetch(user: PageUser) -> User:
    if user is None:
        raise SignInRequired(fetched=True)
    return user


SignedIn = Annotated[User, Depends(signed_in)]
SignedInFetch = Annotated[User, Depends(signed_in_fetch)]


def staff_course(course: str, session: SessionDep, user: SignedIn) -> Course:
    """The signed-in user's course, for its instructors and auditors. Anyone else gets the not-found page: a page
    never tells a student or another course's staff that the course exists."""
    try:
        found = access.own_course(session=session, user=user, name=course)
        access.require_staff(user, action="read the course's pages")
    except (NotFound, Forbidden) as exc:  # both read as "nothing here" on a page
        raise NotFound(f"page of course {course}") from exc
    return found


def instructor_course(course: str, session: SessionDep, user: SignedIn) -> Course:
    found = staff_course(course, session, user)
    if not access.is_instructor(user):
        raise NotFound(f"page of course {course}")
    return found


StaffCourse = Annotated[Course, Depends(staff_course)]
InstructorCourse = Annotated[Course, Depends(instructor_course)]


def instructors_assignment(assignment_id: int, session: SessionDep, user: SignedIn) -> Assignment:
    """An assignment of the signed-in instructor's course; the not-found page for anyone else."""
    try:
        found = assignments.assignment_of(session=session, user=user, assignment_id=assignment_id)
    except NotFound:
        found = None
    if found is None or not access.is_instructor(user):
        raise NotFound(f"assignment {assignment_id}")
    return found


InstructorsAssignment = Annotated[Assignment, Depends(instructors_assignment)]


def signed_in_staff(user: SignedIn) -> User:
    """A signed-in instructor or auditor; a student gets the not-found page (the audit log is not theirs to know)."""
    if not access.is_staff(user):
        raise NotFound("audit log")
    return user


Staff = Annotated[User, Depends(signed_in_staff)]
