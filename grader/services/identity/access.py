"""Who may do what: a student acts on their own submissions, instructors and auditors (staff) read their course's,
and only instructors change it. Raise NotFound where the caller may not know a thing exists, Forbidden where their
role may not act; the web layer's role dependencies (grader.web.deps, grader.pages.auth) call these."""

from __future__ import annotations

from sqlalchemy import select
from sqlalchemy.orm import Session

from grader.core.states import STAFF, Role
from grader.core.models import Course, Submission, User
from grader.services.errors import Forbidden, NotFound

# Primary keys are SQL INTEGER columns: 32-bit on PostgreSQL. An id outside this range names no row.
MAX_ID = 2**31 - 1


def can_read(*, user: User, submission: Submission) -> bool:
    if user.role == Role.STUDENT:
        return submission.student_id == user.id
    return submission.course_id == user.course_id


def readable_submission(*, session: Session, user: User, submission_id: int) -> Submission:
    """The submission if `user` may read it; NotFound otherwise (never revealing that it exists)."""
    submission = session.get(Submission, submission_id) if 0 < submission_id <= MAX_ID else None
    if submission is None or not can_read(user=user, submission=submission):
        raise NotFound(f"submission {submission_id} not found")
    return submission


def is_student(user: User) -> bool:
    return user.role == Role.STUDENT


def is_instructor(user: User) -> bool:
    return user.role == Role.INSTRUCTOR


def is_staff(user: User) -> bool:
    """An instructor or an auditor (grader.core.states.STAFF)."""
    return user.role in STAFF


def require_role(user: User, *roles: Role, action: str) -> None:
    """Forbidden unless the user's role is one of `roles`; `action` completes "... may <action>"."""
    if user.role not in roles:
        allowed = " and ".join(f"{r}s" for r in roles)
        raise Forbidden(f"only {allowed} may {action}; you are signed in as {user.role} {user.name}")


def require_staff(user: User, *, action: str) -> None:
    require_role(user, *STAFF, action=action)


def require_instructor(user: User, *, action: str) -> None:
    require_role(user, Role.INSTRUCTOR, action=action)


def require_course_instructor(user: User, course_id: int, *, action: str, thing: str = "course") -> None:
    """For every change a set-up service makes, checked by the service itself (not only by the page or API
    dependency in front of it): NotFound for anyone outside the course (never confirming what exists), Forbidden for
    a student or an auditor of it."""
    if user.course_id != course_id:
        raise NotFound(f"{thing} not found")
    require_instructor(user, action=action)


def own_course(*, session: Session, user: User, name: str) -> Course:
    """The caller's course by name; NotFound for any other course (another course's name is never confirmed)."""
    course = session.scalar(select(Course).where(Course.name == name))
    if course is None or course.id != user.course_id:
        raise NotFound(f"course {name!r} not found")
    return course
