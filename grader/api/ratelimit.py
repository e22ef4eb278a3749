"""Per-token rate limits: a submission queues real Genesis runs, so each API token may submit at most
settings.rate_limit_submissions (counted by grader.services.quotas); past it the answer is 429 with Retry-After."""

from __future__ import annotations

from typing import Annotated

from fastapi import Depends
from fastapi.security import HTTPAuthorizationCredentials
from limits import parse

from grader.api.deps import CurrentUser, bearer
from grader.api.errors import ErrorWithFields
from grader.core.security import hash_token
from grader.services import quotas
from grader.settings import settings


def limit_submissions(_: CurrentUser,
                      credentials: Annotated[HTTPAuthorizationCredentials | None, Depends(bearer)]) -> None:
    """Counts one submission against the caller's token (after authentication: an unknown token is a 401, not a 429).

    Only the token's hash names the counter, as in the database. Refused attempts are not counted."""
    rule = settings.rate_limit_submissions
    retry_after = quotas.wait_for("submissions", hash_token(credentials.credentials), rule)
    if retry_after is not None:
        raise ErrorWithFields(429, f"too many submissions with this token; try again in {retry_after} s",
                              [{"field": "Authorization", "rule": f"at most {parse(rule)} submissions per token"}],
                              headers={"Retry-After": str(retry_after)})
