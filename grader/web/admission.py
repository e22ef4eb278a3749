"""Who gets into the app and when. A request first waits for its whole body (a deadline, 408), within a cap on what
one client address may have in flight (429); only then does it take one of settings.api_threads admission slots.
The thread pool is as large as the slots, so every admitted request finds a thread and a database connection
(grader.core.db sizes the pool), and a slow or stalled client holds neither."""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable
from contextlib import asynccontextmanager

import anyio
import anyio.to_thread
from starlette.datastructures import Headers
from starlette.requests import Request
from starlette.responses import Response
from uvicorn.middleware.proxy_headers import ProxyHeadersMiddleware

from grader.web.bodies import replaying
from grader.web.errors import API_PREFIX, error
from grader.services.errors import DomainError, Invalid

# A page's refusal made before the app runs: (request, error, status) -> the page's HTML answer.
PageError = Callable[[Request, DomainError, int], Response]


@asynccontextmanager
async def lifespan(app, *, threads: int):
    """Size this event loop's thread pool (anyio's default limiter belongs to the running loop)."""
    anyio.to_thread.current_default_thread_limiter().total_tokens = threads
    yield


class InFlightLimit:
    """Admit at most `limit` HTTP requests into the app at once; later ones wait here, holding neither a thread nor a
    database connection, instead of taking a thread and then waiting on a pool whose connections are held by
    requests that wait for a thread."""

    def __init__(self, app, limit: int):
        self.app = app
        self.limit = limit
        self._slots: anyio.Semaphore | None = None

    async def __call__(self, scope, receive, send):
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        if self._slots is None:  # created on first use, inside the serving event loop
            self._slots = anyio.Semaphore(self.limit)
        async with self._slots:
            await self.app(scope, receive, send)


class BodyDeadline:
    """Read each request's whole body within `deadline_s` before passing it on (408 otherwise), so a client that
    sends its body slowly, or never, waits out here and never holds an admission slot. Reading stops past
    `max_bytes`: what was read is passed on and grader.web.bodies.BodyGuard, the one size rule, answers 413."""

    def __init__(self, app, *, deadline_s: float, max_bytes: int, page_error: PageError):
        self.app, self.deadline_s, self.max_bytes, self.page_error = app, deadline_s, max_bytes, page_error

    async def __call__(self, scope, receive, send):
        if scope["type"] != "http":
            return await self.app(scope, receive, send)
        declared = Headers(scope=scope).get("content-length", "")
        if declared.isdigit() and int(declared) > self.max_bytes:
            return await self.app(scope, receive, send)  # refused by BodyGuard before it reads a byte
        chunks, size, more = [], 0, True
        with anyio.move_on_after(self.deadline_s) as deadline:
            while more and size <= self.max_bytes:
                message = await receive()
                if message["type"] != "http.request":
                    return  # the client went away before sending its body: nobody to answer
                chunks.append(message.get("body", b""))
                size += len(chunks[-1])
                more = message.get("more_body", False)
        if deadline.cancelled_caught:
            rule = {"field": "body", "rule": f"must arrive whole within {self.deadline_s:g} s of the request"}
            return await refuse(scope, receive, send, 408, "request body too slow", [rule], self.page_error,
                                headers={"Connection": "close"})
        await self.app(scope, replaying(b"".join(chunks), receive), send)


class TrustedProxies:
    """The client's address and scheme from X-Forwarded-For / X-Forwarded-Proto, only for a request that comes from
    one of `trusted()` (settings.forwarded_allow_ips: the proxies in front of the API); any other request keeps the
    address it came from, whatever it claims. Nothing is trusted by default: a client on loopback once named 25
    addresses in 25 wrong sign-ins and was refused none. The rule is uvicorn's ProxyHeadersMiddleware (the rightmost
    forwarded address that is no trusted proxy), applied by the app so that it holds under any server; the embedded
    service starts uvicorn with its own handling off (grader.embedded.start_api). Read per request, as ClientLimit's."""

    def __init__(self, app, *, trusted: Callable[[], list[str]]):
        self.app, self.trusted = app, trusted
        self._built: tuple[tuple[str, ...], ProxyHeadersMiddleware] | None = None

    async def __call__(self, scope, receive, send):
        hosts = tuple(self.trusted())
        if not hosts or scope["type"] != "http":
            return await self.app(scope, receive, send)
        if self._built is None or self._built[0] != hosts:
            self._built = (hosts, ProxyHeadersMiddleware(self.app, trusted_hosts=list(hosts)))
        await self._built[1](scope, receive, send)


class ClientLimit:
    """At most `limit()` requests in flight per client address (429 beyond), counted from arrival, so one client
    cannot fill the body-reading stage or the admission slots for everyone. Behind a proxy the address is the one
    TrustedProxies takes from X-Forwarded-For, or every client would share the proxy's. The limit is read per
    request, so a test of many clients behind one in-process address can raise it."""

    def __init__(self, app, *, limit: Callable[[], int], page_error: PageError):
        self.app, self.limit, self.page_error = app, limit, page_error
        self._in_flight: Counter[str] = Counter()

    async def __call__(self, scope, receive, send):
        if scope["type"] != "http":
            return await self.app(scope, receive, send)
        client, limit = (scope.get("client") or ("unknown", 0))[0], self.limit()
        if self._in_flight[client] >= limit:
            rule = {"field": "client", "rule": f"at most {limit} requests in flight from one address"}
            return await refuse(scope, receive, send, 429, "too many requests at once", [rule], self.page_error,
                                headers={"Retry-After": "1"})
        self._in_flight[client] += 1  # no await since the check: one event loop, so no race
        try:
            await self.app(scope, receive, send)
        finally:
            self._in_flight[client] -= 1
            if not self._in_flight[client]:
                del self._in_flight[client]


async def refuse(scope, receive, send, status: int, detail: str, errors: list[dict[str, str]],
                 page_error: PageError, *, headers: dict[str, str]) -> None:
    """JSON {detail, errors} under /v1, the error page elsewhere, as grader.web.errors answers inside the app."""
    if scope["path"].startswith(API_PREFIX):
        response = error(status, detail, errors, headers=headers)
    else:
        response = page_error(Request(scope), Invalid(detail, errors), status)
        response.headers.update(headers)
    await response(scope, receive, send)
