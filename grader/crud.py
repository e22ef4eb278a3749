"""Storage functions for accounts and submissions. Keyword-only arguments; the caller owns the session's commit."""

from __future__ import annotations

from typing import Any

from sqlalchemy import select
from sqlalchemy.orm import Session

from grader.core.security import hash_token, new_token
from grader.core.audit import spec_key
from grader.models import ROLES, ApiToken, CaseRun, Course, Event, Submission, User


def get_or_create_course(*, session: Session, name: str) -> Course:
    course = session.scalar(select(Course).where(Course.name == name))
    if course is None:
        course = Course(name=name)
        session.add(course)
        session.flush()
    return course


def get_or_create_user(*, session: Session, course: Course, name: str, role: str) -> User:
    if role not in ROLES:
        raise ValueError(f"role must be one of {', '.join(ROLES)}, got {role!r}")
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


def create_submission(
    *, session: Session, student: User, lesson: str, sheet: dict[str, Any], specs: list, force_rerun: bool
) -> Submission:
    """The submission and one queued CaseRun per spec, added to the session (commit before enqueueing)."""
    submission = Submission(
        course_id=student.course_id, student_id=student.id, lesson=lesson, sheet=sheet, force_rerun=force_rerun
    )
    session.add(submission)
    session.flush()
    session.add(Event(submission_id=submission.id, state="submitted", detail=f"{len(specs)} case runs"))
    for spec in specs:
        run = CaseRun(
            submission_id=submission.id,
            name=spec.name,
            kind=spec.kind,
            backend=spec.backend,
            precision=spec.precision,
            spec=spec.model_dump(mode="json", exclude_computed_fields=True),
            spec_key=spec_key(spec.model_dump(mode="json", exclude_computed_fields=True)),
        )
        session.add(run)
        session.flush()
        session.add(Event(submission_id=submission.id, case_run_id=run.id, state="queued", detail=f"queue {run.backend}"))
    return submission


def visible_submissions(*, session: Session, user: User, course: Course | None = None):
    """What user may list: a student their own, instructors and auditors their course's."""
    query = select(Submission).order_by(Submission.id)
    if user.role == "student":
        return session.scalars(query.where(Submission.student_id == user.id)).all()
    return session.scalars(query.where(Submission.course_id == (course or user.course).id)).all()


def can_read(*, user: User, submission: Submission) -> bool:
    if user.role == "student":
        return submission.student_id == user.id
    return submission.course_id == user.course_id
