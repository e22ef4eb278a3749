"""Per-person quotas on work that costs a Genesis run no reuse can shorten (audit re-runs), counted by the `limits`
library in settings.rate_limit_storage_url, the same storage as the API's per-token submission limit."""

from __future__ import annotations

import math
import time
from functools import lru_cache

from limits import parse
from limits.storage import storage_from_string
from limits.strategies import MovingWindowRateLimiter

from grader.services.errors import Refused
from grader.settings import settings


@lru_cache
def _limiter(storage_url: str) -> MovingWindowRateLimiter:
    return MovingWindowRateLimiter(storage_from_string(storage_url))


def take(what: str, user_id: int, rule: str, *, field: str) -> None:
    """Count one `what` against the user; past `rule` ("20/hour") raise Refused with the seconds until one frees."""
    item = parse(rule)
    limiter = _limiter(settings.rate_limit_storage_url)
    if not limiter.hit(item, what, str(user_id)):
        reset_at, _ = limiter.get_window_stats(item, what, str(user_id))
        retry_after = max(1, math.ceil(reset_at - time.time()))
        raise Refused(field, f"at most {item} {what} each; try again in {retry_after} s", retry_after,
                      detail=f"too many {what}")
