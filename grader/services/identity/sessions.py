"""Page sign-in sessions: the browser's cookie holds a random 256-bit secret, the table only its sha256; a session
ends when idle too long, at its absolute expiry (never after its token's), or when revoked (sign-out, its token
revoked, the sign-in link that opened it re-issued). Wrong tokens at the sign-in form are counted per client address
(settings.rate_limit_sign_in_failures) and refused past it. The caller commits."""

from __future__ import annotations

import secrets
from datetime import datetime, timedelta

from sqlalchemy import and_, select, update
from sqlalchemy.orm import Session

from grader.core.security import hash_token
from grader.core.models import ApiToken, User, WebSession, utcnow
from grader.services.identity import quotas
from grader.core.settings import settings

# last_seen_at is written at most this often, not on every page and chart a browser loads.
TOUCH_EVERY = timedelta(minutes=1)


def open_session(*, session: Session, user: User, token: ApiToken | None = None, now: datetime | None = None) -> str:
    """A new session for user (signed in with token), created `now`; the clear secret exists only in this return
    value. A sign-in link's session is created at the instant the link was used (its used_at): that is how
    revoke_link_sessions finds it."""
    secret = secrets.token_urlsafe(32)
    now = now or utcnow()
    expires_at = now + timedelta(seconds=settings.session_lifetime_s)
    if token is not None and token.expires_at is not None:
        expires_at = min(expires_at, token.expires_at)
    session.add(WebSession(user_id=user.id, token_id=token.id if token else None, secret_hash=hash_token(secret),
                           created_at=now, last_seen_at=now, expires_at=expires_at))
    session.flush()
    return secret


def _live(row: WebSession | None, now: datetime) -> bool:
    return (row is not None and row.revoked_at is None and now < row.expires_at
            and now - row.last_seen_at < timedelta(seconds=settings.session_idle_s))


def session_user(*, session: Session, secret: str) -> User | None:
    """The user of a live session, noting that it was seen (the caller commits); None for an unknown, expired, idle
    or revoked one."""
    row = seen_session(session=session, secret=secret)
    return row.user if row is not None else None


def seen_session(*, session: Session, secret: str) -> WebSession | None:
    """The live session of this secret, noted as seen (the caller commits); None for an unknown, expired, idle or
    revoked one."""
    row = session.scalar(select(WebSession).where(WebSession.secret_hash == hash_token(secret)))
    now = utcnow()
    if not _live(row, now):
        return None
    if now - row.last_seen_at >= TOUCH_EVERY:
        row.last_seen_at = now
    return row


def unchanged_until(row: WebSession) -> datetime:
    """Until when reading with this live session changes nothing about it: its expiry, its idle end, and the next
    instant a read notes it seen again (TOUCH_EVERY after the last). A read answered without the database before
    then (grader.web.fresh) signs no one out sooner than a full read would."""
    return min(row.expires_at, row.last_seen_at + TOUCH_EVERY,
               row.last_seen_at + timedelta(seconds=settings.session_idle_s))


def revoke_session(*, session: Session, secret: str) -> bool:
    """Ends the session of this secret (sign-out); False if there was no open one."""
    return session.execute(update(WebSession).where(WebSession.secret_hash == hash_token(secret),
                                                    WebSession.revoked_at.is_(None))
                           .values(revoked_at=utcnow())).rowcount > 0


def revoke_link_sessions(*, session: Session, user_id: int, used_at: list[datetime]) -> int:
    """Ends the open sessions the user's sign-in links opened: those with no token created at a link's used_at (the
    instant it was used, grader.services.identity.sign_in_links.redeem); how many."""
    if not used_at:
        return 0
    return session.execute(update(WebSession).where(
        and_(WebSession.user_id == user_id, WebSession.token_id.is_(None), WebSession.revoked_at.is_(None),
             WebSession.created_at.in_(used_at))).values(revoked_at=utcnow())).rowcount


SIGN_IN_FAILURES = "failed sign-ins"


def refuse_failing_address(address: str) -> None:
    """Refused (429 with Retry-After) while `address` has used up its wrong sign-ins (settings.
    rate_limit_sign_in_failures): counted before the token is even looked up, so guessing stops there."""
    quotas.refuse_while_spent(SIGN_IN_FAILURES, address, settings.rate_limit_sign_in_failures, field="token")


def count_failed_sign_in(address: str) -> None:
    """One wrong token from `address` (a right one is never counted)."""
    quotas.spend(SIGN_IN_FAILURES, address, settings.rate_limit_sign_in_failures)


def revoke_sessions(*, session: Session, user_id: int | None = None, token_id: int | None = None) -> int:
    """Ends every open session of a user, or those a token opened; how many."""
    if (user_id is None) == (token_id is None):
        raise ValueError("give exactly one of user_id and token_id")
    which = WebSession.user_id == user_id if user_id is not None else WebSession.token_id == token_id
    return session.execute(update(WebSession).where(which, WebSession.revoked_at.is_(None))
                           .values(revoked_at=utcnow())).rowcount
