"""Per-token rate limits, counted by the `limits` library: a submission queues real Genesis runs, so each API token
may submit at most settings.rate_limit_submissions; past it the answer is 429 with Retry-After."""

from __future__ import annotations

import math
import time
from functools import lru_cache
from typing import Annotated

from fastapi import Depends
from fastapi.security import HTTPAuthorizationCredentials
from limits import parse
from limits.storage import storage_from_string
from limits.strategies import MovingWindowRateLimiter

from grader.api.deps import CurrentUser, bearer
from grader.api.errors import ErrorWithFields
from grader.core.security import hash_token
from grader.settings import settings


@lru_cache
def _limiter(storage_url: str):
    return MovingWindowRateLimiter(storage_from_string(storage_url))


def limit_submissions(_: CurrentUser,
                      credentials: Annotated[HTTPAuthorizationCredentials | None, Depends(bearer)]) -> None:
    """Counts one submission against the caller's token (after authentication: an unknown token is a 401, not a 429).

    Only the token's hash names the counter, as in the database. Refused attempts are not counted."""

    item = parse(settings.rate_limit_submissions)
    limiter, key = _limiter(settings.rate_limit_storage_url), hash_token(credentials.credentials)
    if not limiter.hit(item, "submissions", key):
        reset_at, _ = limiter.get_window_stats(item, "submissions", key)
        retry_after = max(1, math.ceil(reset_at - time.time()))
        raise ErrorWithFields(429, f"too many submissions with this token; try again in {retry_after} s",
                         [{"field": "Authorization", "rule": f"at most {item} submissions per token"}],
                         headers={"Retry-After": str(retry_after)})
