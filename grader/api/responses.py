"""Shared OpenAPI error descriptions, so every documented error has the ErrorBody shape."""

from grader.schemas import ErrorBody

AUTH = {401: {"model": ErrorBody, "description": "Missing, unknown or revoked token"}}
NOT_FOUND = {404: {"model": ErrorBody, "description": "Not found, or not visible to this caller"}}
FORBIDDEN = {403: {"model": ErrorBody, "description": "The caller's role may not do this"}}
INVALID = {
    413: {"model": ErrorBody, "description": "Body over the size limit"},
    422: {"model": ErrorBody, "description": "Invalid body; each error names its field and rule"},
}
