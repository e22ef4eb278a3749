"""Students' sign-in links: a random 256-bit secret in the link, only its sha256 stored; one live link per student
(issuing another revokes the earlier and ends the page sessions the earlier links opened), used once, within
settings.sign_in_link_days. Using one opens the same page session the sign-in form opens (grader.services.identity.sessions).
Look-ups of unknown links are counted per client address (settings.rate_limit_link_guesses) and refused past it, so
nobody can try secrets at speed. The caller commits."""

from __future__ import annotations

import secrets
from dataclasses import dataclass
from datetime import datetime, timedelta

from sqlalchemy import select, update
from sqlalchemy.orm import Session

from grader.core.security import hash_token
from grader.core.timezones import local
from grader.core.models import Course, SignInLink, User, utcnow
from grader.services.setup import course_changes
from grader.services.identity import quotas, sessions
from grader.services.setup.course_changes import ChangeKind
from grader.services.identity.access import require_instructor
from grader.services.errors import Invalid, NotFound
from grader.core.settings import settings
from grader.services.identity import access

PATH = "/sign-in/link/"


def issue(*, session: Session, user: User) -> tuple[str, SignInLink]:
    """A new link secret for a student, revoking any earlier link of theirs not yet used and ending the page sessions
    their used links opened (a re-issue says the earlier link may be in other hands); the clear secret exists only in
    this return value."""
    if not access.is_student(user):
        rule = f"{user.name!r} is on the course staff: sign-in links are for students"
        raise Invalid("not a student", [{"field": "student", "rule": rule}])
    revoke_links(session=session, user_id=user.id)
    used = list(session.scalars(select(SignInLink.used_at).where(SignInLink.user_id == user.id,
                                                                 SignInLink.used_at.is_not(None))))
    sessions.revoke_link_sessions(session=session, user_id=user.id, used_at=used)
    now = utcnow()
    secret = secrets.token_urlsafe(32)
    row = SignInLink(user_id=user.id, secret_hash=hash_token(secret), created_at=now,
                     expires_at=now + timedelta(days=settings.sign_in_link_days))
    session.add(row)
    session.flush()
    return secret, row


def revoke_links(*, session: Session, user_id: int) -> int:
    """Revokes every link of a user not yet used (a re-issue, or their access revoked); how many."""
    return session.execute(update(SignInLink).where(SignInLink.user_id == user_id, SignInLink.used_at.is_(None),
                                                    SignInLink.revoked_at.is_(None))
                           .values(revoked_at=utcnow())).rowcount


def issue_for(*, session: Session, course: Course, student_name: str, by: User) -> tuple[str, SignInLink]:
    """Re-issue one student's link (the earlier one stops working), recorded with who issued it; Invalid for anyone
    not a student of the course; NotFound for someone outside the course and Forbidden for anyone but its
    instructors (checked here, not only by the page or route). Commits."""
    if by.course_id != course.id:
        raise NotFound(f"course {course.name!r} not found")
    require_instructor(by, action="issue a sign-in link")
    student = session.scalar(select(User).where(User.course_id == course.id, User.name == student_name))
    if student is None:
        raise Invalid("unknown student", [{"field": "student", "rule": f"no student {student_name!r} in this course"}])
    secret, row = issue(session=session, user=student)
    course_changes.record(session=session, course=course, by=by, kind=ChangeKind.SIGN_IN_LINK_ISSUED,
                          summary=f"new sign-in link for {student.name} (the earlier one revoked)",
                          detail={"student": student.name})
    session.commit()
    return secret, row


def find(*, session: Session, secret: str) -> SignInLink | None:
    return session.scalar(select(SignInLink).where(SignInLink.secret_hash == hash_token(secret))) if secret else None


LINK_GUESSES = "unknown sign-in links"


def look_up(*, session: Session, secret: str, address: str) -> SignInLink | None:
    """The link of this secret, for a client at `address`: Refused (429 with Retry-After) while the address has used
    up its look-ups of unknown links, and an unknown one counted against it (a known link, used or not, never is)."""
    quotas.refuse_while_spent(LINK_GUESSES, address, settings.rate_limit_link_guesses, field="link")
    row = find(session=session, secret=secret)
    if row is None:
        quotas.spend(LINK_GUESSES, address, settings.rate_limit_link_guesses)
    return row


def refusal(row: SignInLink | None, now: datetime | None = None) -> str | None:
    """Why this link cannot sign anyone in (shown on the page), or None when it can."""
    now = now or utcnow()
    if row is None:
        return ("This sign-in link is unknown. Check that the whole link was copied, or ask your instructor for a "
                "new one.")
    tz = row.user.course.timezone
    if row.used_at is not None:
        return (f"This sign-in link was already used, at {local(row.used_at, tz)}; a link works once. "
                "Ask your instructor for a new one if you are not signed in.")
    if row.revoked_at is not None:
        return (f"This sign-in link was revoked at {local(row.revoked_at, tz)}: a newer link was issued, or your "
                "access was withdrawn. Use the newest link you were sent, or ask your instructor.")
    if now >= row.expires_at:
        return f"This sign-in link expired at {local(row.expires_at, tz)}. Ask your instructor for a new one."
    return None


@dataclass(frozen=True)
class Redeemed:
    """A used link: the new page session's secret and its user, or why the link was refused (both None then)."""

    session_secret: str | None = None
    user: User | None = None
    refusal: str | None = None


def redeem(*, session: Session, secret: str, address: str) -> Redeemed:
    """Uses the link and opens a page session (look_up's count for `address` first). The link is marked used by one
    conditional update, so two requests racing with the same link cannot both sign in; the session is opened at the
    instant the link is marked used, which names it as this link's (sessions.revoke_link_sessions)."""
    row = look_up(session=session, secret=secret, address=address)
    now = utcnow()
    why = refusal(row, now)
    if why is not None:
        return Redeemed(refusal=why)
    taken = session.execute(update(SignInLink).where(
        SignInLink.id == row.id, SignInLink.used_at.is_(None), SignInLink.revoked_at.is_(None),
        SignInLink.expires_at > now).values(used_at=now)).rowcount
    if taken != 1:  # another request used or revoked it after we read it
        session.rollback()
        why = refusal(find(session=session, secret=secret), now)
        return Redeemed(refusal=why or "This sign-in link was just used.")
    return Redeemed(sessions.open_session(session=session, user=row.user, now=now), row.user)
