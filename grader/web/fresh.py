"""A 304 with no database query: a conditional read of a complete report that has not changed is answered from the
validator store (grader.core.freshness) before any dependency opens a database session.

For the four readable answers of a complete report (the report page, results.json, /v1/submissions/ID and its
/grade) `FreshReads`, an ASGI middleware, reads in one round trip the write epoch and this reader's entry for this
address. The entry is keyed by everything the answer can vary by, taken raw from the request: the Authorization
and Cookie headers (the reader and the language cookie: a credential is only ever hashed), the method, scheme,
host, path and query, and Accept-Language. It answers 304 (with the ETag and Cache-Control the route would give)
only where the entry was written under the current epoch, its `not_after` is still ahead, and If-None-Match names
its ETag; anything else goes on to the route unchanged, which carries the epoch read here (read before any of the
request's database reads) to `remember`, called by grader.web.etag.conditional for a complete report.

An entry's `not_after` is the earliest of: the credential's end (a token's expiry; a page session's expiry, and the
next instant at which a read would note the session as seen again, so that skipping the full read never lets a
session go idle sooner than it would have: grader.services.identity.sessions.TOUCH_EVERY), the next instant at which
time alone shows the reader a withheld item (a due date passing: grader.services.submissions.visibility.
next_shown_at), and freshness.ENTRY_TTL_S ahead. Everything else that can change an answer is a write, and every
write changes the epoch.
"""

from __future__ import annotations

import re
from datetime import datetime, timedelta

from starlette.requests import Request

from grader.core import clock, freshness

# Changes every validator when what a body is made of changes shape (a new field on the page or in the JSON), so a
# browser's stored copy from an older release is never confirmed by a newer one: part of grader.web.etag's
# validators and of the entry keys here (an entry an older release kept is never read by a newer one).
SHAPE = "1"
CACHE_CONTROL = "private, no-cache"  # the browser keeps it for its own user and asks again each time
# The four answers validated by grader.web.etag.report_state (series.json and the rest always take the full path).
PATHS = re.compile(r"^(/v1)?/submissions/[0-9]+(/results\.json|/grade)?$")
SESSION_COOKIE = "grader_session"  # grader.pages.auth.COOKIE (the pages' own module may not be imported here)
KEYED = (b"authorization", b"cookie", b"host", b"accept-language", b"if-none-match")
STATE = "fresh"  # request.state.fresh: (entry key, epoch as read before the request's database reads)
UNTIL = "fresh_until"  # request.state.fresh_until: when the request's credential stops being trusted from memory


def _key(scope, headers: dict[bytes, bytes]) -> str | None:
    """The entry key of this request, or None where it names no credential (nothing to answer from memory). The
    whole Cookie header is part of it (the session and language cookies among whatever else it holds)."""
    authorization = headers.get(b"authorization", b"").decode("latin-1")
    cookie = headers.get(b"cookie", b"").decode("latin-1")
    if not authorization and SESSION_COOKIE not in cookie:
        return None
    return freshness.entry_key(
        SHAPE, authorization, cookie, scope["method"], scope.get("scheme", "http"),
        headers.get(b"host", b"").decode("latin-1"), scope.get("root_path", ""), scope["path"],
        scope.get("query_string", b"").decode("latin-1"), headers.get(b"accept-language", b"").decode("latin-1"))


class FreshReads:
    """The fast path above; installed inside the admission middleware (grader.main), so a 304 from memory is
    admitted, logged and given the security headers like any answer."""

    def __init__(self, app):
        self.app = app

    async def __call__(self, scope, receive, send):
        if scope["type"] != "http" or scope["method"] != "GET" or not PATHS.match(scope["path"]):
            return await self.app(scope, receive, send)
        names = [k for k, _ in scope["headers"]]
        if any(names.count(k) > 1 for k in KEYED):  # which one the doors read is theirs to say: the full path
            return await self.app(scope, receive, send)
        headers = dict(scope["headers"])
        key = _key(scope, headers)
        if key is None:
            return await self.app(scope, receive, send)
        epoch, entry = freshness.read(key)
        if epoch is not None:
            tag = entry.get("etag") if entry else None
            none_match = headers.get(b"if-none-match", b"").decode("latin-1")
            if tag and none_match and freshness.valid(entry, epoch) and matches_header(none_match, tag):
                await send({"type": "http.response.start", "status": 304,
                            "headers": [(b"etag", tag.encode()), (b"cache-control", CACHE_CONTROL.encode())]})
                await send({"type": "http.response.body", "body": b""})
                return
            scope.setdefault("state", {})[STATE] = (key, epoch)
        return await self.app(scope, receive, send)


def matches_header(header: str | None, etag: str) -> bool:
    """Whether an If-None-Match value names `etag` (weak comparison, as RFC 9110 asks for If-None-Match)."""
    if not header:
        return False
    if header.strip() == "*":
        return True
    tags = {t.strip().removeprefix("W/") for t in header.split(",")}
    return etag in tags


def credential_until(request: Request, until: datetime | None) -> None:
    """Called by the sign-in dependencies: the request's credential may be trusted from memory until `until` (None:
    no end of its own)."""
    request.state.fresh_until = (until,)


def remember(request: Request, etag: str, until: datetime | None) -> None:
    """After a complete report's full read: keep its validator for this reader and address, under the epoch read
    before this request's first database read, until the earliest of `until` (time-driven changes), the
    credential's end and freshness.ENTRY_TTL_S."""
    state = getattr(request.state, STATE, None)
    credential = getattr(request.state, UNTIL, None)
    if state is None or credential is None:
        return
    key, epoch = state
    bounds = [b for b in (until, credential[0]) if b is not None]
    not_after = min(bounds + [clock.now() + timedelta(seconds=freshness.ENTRY_TTL_S)])
    freshness.remember(key, etag=etag, epoch=epoch, not_after=not_after)
