"""Per-person and per-address quotas on costly or guessable work, counted by the `limits` library in
settings.rate_limit_storage_url (memory:// for one process, Redis when several API processes serve), so every door
(the API, the pages, the command line through the API) counts against the same store: submissions per person, audit
re-runs per staff member, draft saves per person, review requests per student, and failed sign-ins and unknown
sign-in links per client address. Past a quota the service raises Refused with the seconds until one frees, which
the web layer answers 429 with Retry-After (grader.web.errors), as JSON or as a page."""

from __future__ import annotations

import math
import threading
import time
from functools import lru_cache

from limits import parse
from limits.storage import storage_from_string
from limits.strategies import MovingWindowRateLimiter

from grader.services.errors import Refused
from grader.core.settings import settings


_MAKING = threading.Lock()


@lru_cache
def _limiter(storage_url: str) -> MovingWindowRateLimiter:
    # One thread at a time: the storage imports its client (redis) lazily, and a second request thread reading the
    # half-imported module's version got "minimum version of 3.0 for 'redis' ... Found 0.0.0" (a 500) on a fresh
    # API process's first concurrent submissions (tests/integration/test_api_processes.py).
    with _MAKING:
        return MovingWindowRateLimiter(storage_from_string(storage_url))


def _seconds_until_free(item, what: str, key: str) -> int:
    reset_at, _ = _limiter(settings.rate_limit_storage_url).get_window_stats(item, what, key)
    return max(1, math.ceil(reset_at - time.time()))


def wait_for(what: str, key: str, rule: str) -> int | None:
    """Count one `what` against `key` under `rule` ("20/hour"): None when within it, else the seconds until one
    frees (a refused one is not counted)."""
    item = parse(rule)
    if _limiter(settings.rate_limit_storage_url).hit(item, what, key):
        return None
    return _seconds_until_free(item, what, key)


def rule_text(what: str, rule: str, per: str) -> str:
    """The rule a refusal names, the same at every door: "at most 10 per 1 minute submissions per person"."""
    return f"at most {parse(rule)} {what} per {per}"


def refusal(what: str, rule: str, per: str, retry_after: int, *, field: str) -> Refused:
    return Refused(field, rule_text(what, rule, per), retry_after,
                   detail=f"too many {what}; try again in {retry_after} s")


def take(what: str, key: int | str, rule: str, *, field: str, per: str = "person") -> None:
    """Count one `what` against `key` (a user id, an address); past `rule` raise Refused (429 with Retry-After) naming
    `field` and the rule. A refused one is not counted."""
    retry_after = wait_for(what, str(key), rule)
    if retry_after is not None:
        raise refusal(what, rule, per, retry_after, field=field)


def refuse_while_spent(what: str, key: str, rule: str, *, field: str, per: str = "address") -> None:
    """Refused (429) while `key` has already used up `rule` of `what` (counted by `spend`), counting nothing itself:
    for failures only, such as wrong sign-ins, so that a person who gets it right is never counted."""
    item = parse(rule)
    if not _limiter(settings.rate_limit_storage_url).test(item, what, key):
        raise refusal(what, rule, per, _seconds_until_free(item, what, key), field=field)


def spend(what: str, key: str, rule: str) -> None:
    """Count one failure of `what` against `key` (see refuse_while_spent)."""
    _limiter(settings.rate_limit_storage_url).hit(parse(rule), what, key)
