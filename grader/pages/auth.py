"""Who is looking at a page: the session cookie set at sign-in, or the API's `Authorization: Bearer` header.

The cookie holds the caller's API token (HttpOnly, SameSite=Strict, Secure outside development): the pages and
the API share one credential and one revocation. The API itself accepts only the header, so a page can never be
used to submit on a student's behalf from another site.
"""

from __future__ import annotations

from typing import Annotated

from fastapi import Depends, Request

from grader.services import access, accounts, assignments
from grader.api.deps import SessionDep
from grader.core.states import STAFF, Role
from grader.models import Assignment, Course, User
from grader.services.errors import Forbidden, NotFound
from grader.settings import settings

COOKIE = "grader_session"
COOKIE_MAX_AGE_S = 12 * 3600


def page_user(request: Request, session: SessionDep) -> User | None:
    """The signed-in user, or None (the page then redirects to the sign-in form)."""
    header = request.headers.get("authorization", "")
    scheme, _, token = header.partition(" ")
    if scheme.lower() != "bearer" or not token:
        token = request.cookies.get(COOKIE, "")
    return accounts.user_by_token(session=session, token=token.strip()) if token else None


PageUser = Annotated[User | None, Depends(page_user)]


def set_session_cookie(response, token: str) -> None:
    response.set_cookie(COOKIE, token, max_age=COOKIE_MAX_AGE_S, httponly=True, samesite="strict",
                        secure=settings.environment == "production", path="/")


def clear_session_cookie(response) -> None:
    response.delete_cookie(COOKIE, path="/")


class SignInRequired(Exception):
    """Nobody is signed in: the page answers with a redirect to the sign-in form (grader.pages.errors)."""


def signed_in(user: PageUser) -> User:
    if user is None:
        raise SignInRequired()
    return user


SignedIn = Annotated[User, Depends(signed_in)]


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
    if user.role != Role.INSTRUCTOR:
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
    if found is None or user.role != Role.INSTRUCTOR:
        raise NotFound(f"assignment {assignment_id}")
    return found


InstructorsAssignment = Annotated[Assignment, Depends(instructors_assignment)]


def signed_in_staff(user: SignedIn) -> User:
    """A signed-in instructor or auditor; a student gets the not-found page (the audit log is not theirs to know)."""
    if user.role not in STAFF:
        raise NotFound("audit log")
    return user


Staff = Annotated[User, Depends(signed_in_staff)]
