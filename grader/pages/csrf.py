"""Cross-site form posts are refused by origin, as Go 1.25's http.CrossOriginProtection does: a browser says where a
request comes from (Sec-Fetch-Site, or else Origin), so no form needs a token. SameSite alone let a cross-site POST
sign a victim in as the attacker, and leaves any sibling site trusted.

- Sec-Fetch-Site present: only `same-origin` or `none` (typed by the user) pass.
- else Origin present: its host[:port] must be the request's Host (not its scheme, as in Go: behind a TLS-terminating
  proxy the app sees http while the browser's Origin says https).
- neither: not a browser (curl, the command line, a test client), which carries no victim's cookie: allowed.
"""

from __future__ import annotations

from urllib.parse import urlsplit

from fastapi import Request

from grader.services.errors import DomainError

SAFE_METHODS = frozenset({"GET", "HEAD", "OPTIONS", "TRACE"})


class CrossSiteRefused(DomainError):
    """An unsafe page request another site made a browser send: the error page, 403 (grader.pages.errors)."""

    def __init__(self, field: str, rule: str):
        super().__init__("cross-site request refused", [{"field": field, "rule": rule}])


def refusal(method: str, headers) -> CrossSiteRefused | None:
    """Why a request with these headers is refused, or None when it may go on."""
    if method.upper() in SAFE_METHODS:
        return None
    site = headers.get("sec-fetch-site")
    if site is not None:
        if site.lower() in ("same-origin", "none"):
            return None
        return CrossSiteRefused("header.Sec-Fetch-Site",
                                f"is {site!r}: a form is only taken from this site's own pages")
    origin = headers.get("origin")
    if origin is None:
        return None
    host = headers.get("host", "")
    try:
        origin_host = urlsplit(origin).netloc if origin.lower() != "null" else ""
    except ValueError:
        origin_host = ""
    if origin_host and origin_host.lower() == host.lower():
        return None
    return CrossSiteRefused("header.Origin", f"is {origin!r}, not this site ({host}): a form is only taken from "
                                             "this site's own pages")


def same_origin(request: Request) -> None:
    """A dependency of every page route: refuses an unsafe request that another site sent."""
    refused = refusal(request.method, request.headers)
    if refused is not None:
        raise refused
