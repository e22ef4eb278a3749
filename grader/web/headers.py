"""Security headers on every answer: a Content-Security-Policy that loads nothing from elsewhere and runs no inline
script, no framing, no MIME sniffing, no referrer outside the site, and `private, no-store` on everything but the
static assets, since pages, exports and most of /v1 carry grades or names. A route that sets its own
Content-Security-Policy or Cache-Control (the API docs, the dashboard's revalidated charts) keeps it."""

from __future__ import annotations

import base64
import hashlib

from starlette.datastructures import MutableHeaders

STATIC_PREFIX = "/static/"
# The pages use no script and no style attribute; form-action and base-uri are not covered by default-src.
PAGE_POLICY = ("default-src 'self'; object-src 'none'; base-uri 'none'; form-action 'self'; "
               "frame-ancestors 'none'")
HEADERS = {
    "X-Content-Type-Options": "nosniff",
    "Referrer-Policy": "same-origin",
    "X-Frame-Options": "DENY",  # frame-ancestors for browsers without CSP level 2
}


def docs_policy(inline_script: str) -> str:
    """The policy of the API docs page: Swagger UI's one inline start-up script by its hash; its own style
    attributes and data: icons (it renders no stored input, so inline styles risk nothing there)."""
    digest = base64.b64encode(hashlib.sha256(inline_script.encode()).digest()).decode()
    return (f"default-src 'self'; script-src 'self' 'sha256-{digest}'; style-src 'self' 'unsafe-inline'; "
            "img-src 'self' data:; object-src 'none'; base-uri 'none'; form-action 'self'; frame-ancestors 'none'")


def secure(headers: MutableHeaders, path: str) -> None:
    """The headers above on one answer (its own Content-Security-Policy and Cache-Control kept)."""
    for name, value in HEADERS.items():
        headers[name] = value
    headers.setdefault("Content-Security-Policy", PAGE_POLICY)
    if not path.startswith(STATIC_PREFIX):
        headers.setdefault("Cache-Control", "private, no-store")


class SecurityHeaders:
    """ASGI middleware adding the headers above to each HTTP answer's start. An unhandled error's 500 is answered
    outside every middleware (Starlette's ServerErrorMiddleware): grader.web.errors' handler of it calls `secure`."""

    def __init__(self, app):
        self.app = app

    async def __call__(self, scope, receive, send):
        if scope["type"] != "http":
            return await self.app(scope, receive, send)
        async def send_with_headers(message):
            if message["type"] == "http.response.start":
                message.setdefault("headers", [])
                secure(MutableHeaders(scope=message), scope["path"])
            await send(message)

        await self.app(scope, receive, send_with_headers)
