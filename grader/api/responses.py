"""The OpenAPI description of every error status a route can answer, each with the ErrorBody shape in JSON.

Routes declare exactly the statuses they return (`errors(401, 404, 422)`); a route whose success is CSV or a file
still answers its errors in JSON, and says so (`csv_ok` documents the success; the errors stay application/json).
"""

from __future__ import annotations

from grader.core.schemas import ErrorBody

DESCRIPTIONS = {
    401: "Missing, malformed, unknown or revoked bearer token",
    403: "The caller's role may not do this",
    404: "Not found, or not visible to this caller",
    409: "Conflicts with the current state; the detail says which",
    413: "Body over the size limit",
    422: "Invalid request; each error names its field (a dotted path in the body, or path.NAME, query.NAME) and "
         "the rule it breaks",
    429: "Too many requests with this token; retry after Retry-After seconds",
}
RETRY_AFTER = {"Retry-After": {"description": "Seconds until the token may submit again",
                               "schema": {"type": "integer", "minimum": 1}}}


def errors(*codes: int, **described: str) -> dict[int | str, dict]:
    """OpenAPI responses for these error statuses; `described` overrides a description (e.g. _409="...")."""
    out: dict[int | str, dict] = {}
    for code in codes:
        out[code] = {"model": ErrorBody, "description": described.get(f"_{code}", DESCRIPTIONS[code])}
        if code == 429:
            out[code]["headers"] = RETRY_AFTER
    return out


def csv_ok(description: str) -> dict[int, dict]:
    return {200: {"description": description, "content": {"text/csv": {"schema": {"type": "string"}}}}}


def file_ok(description: str, *media_types: str) -> dict[int, dict]:
    """A file download: bytes, except a JSON file, whose body is a JSON document (provenance, metrics, spec)."""
    return {200: {"description": description,
                  "content": {m: {"schema": {"type": "object"} if m == "application/json"
                                  else {"type": "string", "format": "binary"}} for m in media_types}}}
