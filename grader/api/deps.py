"""Request dependencies: a database session per request and the caller, from a bearer token."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Annotated

from fastapi import Depends, HTTPException, Path, status
from fastapi.security import HTTPAuthorizationCredentials, HTTPBearer
from sqlalchemy.orm import Session

from grader import crud
from grader.core.db import new_session
from grader.models import Submission, User

# Primary keys are SQL INTEGER columns: 32-bit on PostgreSQL, the deployment database. An id outside this range names
# no row on either database (SQLite cannot even bind one above 2**63 - 1: that was a 500), so it is refused up front
# with 422 naming the parameter, and the range is in the OpenAPI schema.
MAX_ID = 2**31 - 1
RowId = Annotated[int, Path(ge=1, le=MAX_ID, description=f"A row id, 1 to {MAX_ID}")]
# Course and case-run names as the tables store them (String(64)); a longer one cannot exist.
Name = Annotated[str, Path(min_length=1, max_length=64)]

bearer = HTTPBearer(auto_error=False, description="An API token from `grader admin token`.")


def get_session() -> Iterator[Session]:
    with new_session() as session:
        yield session


SessionDep = Annotated[Session, Depends(get_session)]


def current_user(session: SessionDep,
                 credentials: Annotated[HTTPAuthorizationCredentials | None, Depends(bearer)]) -> User:
    if credentials is None or credentials.scheme.lower() != "bearer":
        raise HTTPException(status.HTTP_401_UNAUTHORIZED, "missing bearer token", {"WWW-Authenticate": "Bearer"})
    user = crud.user_by_token(session=session, token=credentials.credentials)
    if user is None:
        raise HTTPException(status.HTTP_401_UNAUTHORIZED, "unknown or revoked token", {"WWW-Authenticate": "Bearer"})
    return user


CurrentUser = Annotated[User, Depends(current_user)]


def readable_submission(submission_id: RowId, session: SessionDep, user: CurrentUser) -> Submission:
    """The submission if the caller may read it; 404 otherwise (never revealing that it exists)."""
    submission = session.get(Submission, submission_id)
    if submission is None or not crud.can_read(user=user, submission=submission):
        raise HTTPException(status.HTTP_404_NOT_FOUND, f"submission {submission_id} not found")
    return submission


SubmissionDep = Annotated[Submission, Depends(readable_submission)]
