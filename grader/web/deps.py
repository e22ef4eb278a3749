"""Request dependencies: a database session per request, the caller from a bearer token, and the roles a route
needs (declared on the route: `user: InstructorUser`, `course: StaffCourse`; the rules are grader.services.identity.access)."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Annotated

from fastapi import Depends, HTTPException, Path, Request, status
from fastapi.security import HTTPAuthorizationCredentials, HTTPBearer
from sqlalchemy.orm import Session

from grader.services.identity import access, accounts
from grader.web import fresh
from grader.core.db import new_session
from grader.core.models import Course, Submission, User

# Primary keys are SQL INTEGER columns: 32-bit on PostgreSQL, the deployment database. An id outside this range names
# no row on either database (SQLite cannot even bind one above 2**63 - 1: that was a 500), so it is refused up front
# with 422 naming the parameter, and the range is in the OpenAPI schema.
MAX_ID = access.MAX_ID
RowId = Annotated[int, Path(ge=1, le=MAX_ID, description=f"A row id, 1 to {MAX_ID}")]
# Course and case-run names as the tables store them (String(64)); a longer one cannot exist.
Name = Annotated[str, Path(min_length=1, max_length=64)]

bearer = HTTPBearer(auto_error=False, description="An API token from `grader admin token`.")


def get_session() -> Iterator[Session]:
    with new_session() as session:
        yield session


SessionDep = Annotated[Session, Depends(get_session)]


def current_user(request: Request, session: SessionDep,
                 credentials: Annotated[HTTPAuthorizationCredentials | None, Depends(bearer)]) -> User:
    if credentials is None or credentials.scheme.lower() != "bearer":
        raise HTTPException(status.HTTP_401_UNAUTHORIZED, "missing bearer token", {"WWW-Authenticate": "Bearer"})
    row = accounts.find_token(session=session, token=credentials.credentials)
    refusal = accounts.token_refusal(row)
    if refusal is not None:  # says which: unknown, revoked or expired
        raise HTTPException(status.HTTP_401_UNAUTHORIZED, refusal, {"WWW-Authenticate": "Bearer"})
    fresh.credential_until(request, row.expires_at)  # a revocation is a write: grader.web.fresh
    return row.user


CurrentUser = Annotated[User, Depends(current_user)]


def readable_submission(submission_id: RowId, session: SessionDep, user: CurrentUser) -> Submission:
    """The submission if the caller may read it; 404 otherwise (never revealing that it exists)."""
    return access.readable_submission(session=session, user=user, submission_id=submission_id)


SubmissionDep = Annotated[Submission, Depends(readable_submission)]


def staff_user(user: CurrentUser) -> User:
    access.require_staff(user, action="do this")
    return user


def instructor_user(user: CurrentUser) -> User:
    access.require_instructor(user, action="do this")
    return user


StaffUser = Annotated[User, Depends(staff_user)]
InstructorUser = Annotated[User, Depends(instructor_user)]


def member_course(course: Name, session: SessionDep, user: CurrentUser) -> Course:
    """The caller's own course by its name in the path; 404 for any other, whether or not it exists."""
    return access.own_course(session=session, user=user, name=course)


MemberCourse = Annotated[Course, Depends(member_course)]


def staff_course(course: MemberCourse, user: CurrentUser) -> Course:
    """The caller's own course, for its instructors and auditors (404 for another course first, then 403)."""
    access.require_staff(user, action="read the course's records")
    return course


def instructor_course(course: MemberCourse, user: CurrentUser) -> Course:
    access.require_instructor(user, action="change the course")
    return course


StaffCourse = Annotated[Course, Depends(staff_course)]
InstructorCourse = Annotated[Course, Depends(instructor_course)]
