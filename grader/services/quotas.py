"""Per-person quotas on costly work, counted by the `limits` library in settings.rate_limit_storage_url: the API's
per-token submission limit (grader.api.ratelimit) and each staff member's audit re-runs."""

from __future__ import annotations

import math
import threading
import time
from functools import lru_cache

from limits import parse
from limits.storage import storage_from_string
from limits.strategies import MovingWindowRateLimiter

from grader.services.errors import Refused
from grader.settings import settings


_MAKING = threading.Lock()


@lru_cache
def _limiter(storage_url: str) -> MovingWindowRateLimiter:
    # One thread at a time: the storage imports its client (redis) lazily, and a second request thread reading the
    # half-imported module's version got "minimum version of 3.0 for 'redis' ... Found 0.0.0" (a 500) on a fresh
    # API process's first concurrent submissions (tests/integration/test_api_processes.py).
    with _MAKING:
        return MovingWindowRateLimiter(storage_from_string(storage_url))


def wait_for(what: str, key: str, rule: str) -> int | None:
    """Count one `what` against `key` under `rule` ("20/hour"): None when within it, else the seconds until one
    frees (a refused one is not counted)."""
    item = parse(rule)
    limiter = _limiter(settings.rate_limit_storage_url)
    if limiter.hit(item, what, key):
        return None
    reset_at, _ = limiter.get_window_stats(item, what, key)
    return max(1, math.ceil(reset_at - time.time()))


def take(what: str, user_id: int, rule: str, *, field: str) -> None:
    """Count one `what` against the user; past `rule` raise Refused with the seconds until one frees."""
    retry_after = wait_for(what, str(user_id), rule)
    if retry_after is not None:
        raise Refused(field, f"at most {parse(rule)} {what} each; try again in {retry_after} s", retry_after,
                      detail=f"too many {what}")
