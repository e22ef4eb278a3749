"""Courses, people and their API tokens (expiring, revocable). Keyword-only arguments; the caller owns the session's
commit."""

from __future__ import annotations

from datetime import timedelta

from sqlalchemy import select, update
from sqlalchemy.orm import Session

from grader.core.security import hash_token, new_token
from grader.core.states import Role, values
from grader.core.models import ApiToken, Course, User, utcnow
from grader.services.identity import sessions, sign_in_links
from grader.services.identity.access import MAX_ID
from grader.services.errors import Invalid, NotFound
from grader.core.settings import settings

MAX_TOKEN_DAYS = 3650


def get_or_create_course(*, session: Session, name: str) -> Course:
    course = session.scalar(select(Course).where(Course.name == name))
    if course is None:
        course = Course(name=name)
        session.add(course)
        session.flush()
    return course


def get_or_create_user(*, session: Session, course: Course, name: str, role: str) -> User:
    if role not in values(Role):
        raise ValueError(f"role must be one of {', '.join(values(Role))}, got {role!r}")
    user = session.scalar(select(User).where(User.course_id == course.id, User.name == name))
    if user is None:
        user = User(course_id=course.id, name=name, role=role)
        session.add(user)
        session.flush()
    elif user.role != role:
        raise ValueError(f"user {name!r} already exists in {course.name!r} as {user.role}")
    return user


def create_token(*, session: Session, user: User, expires_in_days: int | None = None) -> str:
    """A new token for user, expiring after expires_in_days (default settings.token_lifetime_days); the only time
    the clear token exists is this return value."""
    days = settings.token_lifetime_days if expires_in_days is None else expires_in_days
    if not 1 <= days <= MAX_TOKEN_DAYS:
        raise Invalid("token lifetime refused",
                      [{"field": "expires_in_days", "rule": f"a whole number of days from 1 to {MAX_TOKEN_DAYS}"}])
    token = new_token()
    session.add(ApiToken(user_id=user.id, token_hash=hash_token(token), expires_at=utcnow() + timedelta(days=days)))
    session.flush()
    return token


def find_token(*, session: Session, token: str) -> ApiToken | None:
    """The token's row whether or not it still works (token_refusal says); None for an unknown token."""
    return session.scalar(select(ApiToken).where(ApiToken.token_hash == hash_token(token))) if token else None


def token_refusal(row: ApiToken | None) -> str | None:
    """Why this token no longer signs anyone in (unknown, revoked, expired), or None when it does."""
    if row is None:
        return "unknown token"
    if row.revoked_at is not None:
        return f"token revoked at {row.revoked_at:%Y-%m-%d %H:%M} UTC; ask for a new one"
    if row.expires_at is not None and utcnow() >= row.expires_at:
        return f"token expired at {row.expires_at:%Y-%m-%d %H:%M} UTC; ask for a new one"
    return None


def user_by_token(*, session: Session, token: str) -> User | None:
    row = find_token(session=session, token=token)
    return row.user if token_refusal(row) is None else None


def revoke_token(*, session: Session, token_or_id: str) -> ApiToken:
    """Revokes a token, given as the token itself or its row id, and ends the page sessions it opened; a token
    already revoked stays as it was."""
    token_or_id = token_or_id.strip()
    if token_or_id.isdigit():
        row = session.get(ApiToken, int(token_or_id)) if int(token_or_id) <= MAX_ID else None
    else:
        row = find_token(session=session, token=token_or_id)
    if row is None:
        raise NotFound(f"token {token_or_id if token_or_id.isdigit() else '(given)'} not found")
    if row.revoked_at is None:
        row.revoked_at = utcnow()
        sessions.revoke_sessions(session=session, token_id=row.id)
        session.flush()
    return row


def revoke_student_tokens(*, session: Session, course: Course, name: str) -> tuple[int, int]:
    """Revokes every working token and unused sign-in link of a student of the course and ends their page sessions:
    (tokens, sessions). NotFound for a name that is not a student of this course."""
    student = session.scalar(select(User).where(User.course_id == course.id, User.name == name,
                                                User.role == Role.STUDENT))
    if student is None:
        raise NotFound(f"student {name!r} not found")
    now = utcnow()
    tokens = session.execute(update(ApiToken).where(ApiToken.user_id == student.id, ApiToken.revoked_at.is_(None))
                             .values(revoked_at=now)).rowcount
    sign_in_links.revoke_links(session=session, user_id=student.id)  # else a mailed link would let them back in
    return tokens, sessions.revoke_sessions(session=session, user_id=student.id)


def tokens_of(*, session: Session, course: str, name: str) -> list[ApiToken]:
    """Every token of user `name` of course `course`, working or not, oldest first."""
    user = session.scalar(select(User).join(Course).where(Course.name == course, User.name == name))
    if user is None:
        raise NotFound(f"user {name!r} of course {course!r} not found")
    return list(session.scalars(select(ApiToken).where(ApiToken.user_id == user.id).order_by(ApiToken.id)))
