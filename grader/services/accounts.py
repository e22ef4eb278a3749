"""Courses, people and their API tokens. Keyword-only arguments; the caller owns the session's commit."""

from __future__ import annotations

from sqlalchemy import select
from sqlalchemy.orm import Session

from grader.core.security import hash_token, new_token
from grader.core.states import Role, values
from grader.models import ApiToken, Course, User


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


def create_token(*, session: Session, user: User) -> str:
    """A new token for user; the only time the clear token exists is this return value."""
    token = new_token()
    session.add(ApiToken(user_id=user.id, token_hash=hash_token(token)))
    session.flush()
    return token


def user_by_token(*, session: Session, token: str) -> User | None:
    row = session.scalar(select(ApiToken).where(ApiToken.token_hash == hash_token(token), ApiToken.revoked_at.is_(None)))
    return row.user if row else None
