"""Collects the routers under /v1: one package per service context (grader/services/<context>), health apart."""

from fastapi import APIRouter, Depends, Request
from fastapi.exceptions import RequestValidationError

from grader.api.routes import health
from grader.api.routes.identity import sign_in_links, tokens
from grader.api.routes.lti import registrations
from grader.api.routes.reports import audit, exports
from grader.api.routes.rubrics import versions
from grader.api.routes.setup import assignments, courses, variants
from grader.api.routes.submissions import case_runs, files, notebooks, review_requests, sheets, submit


PREFIX = "/v1"
_DECLARED: dict[tuple[str, str], frozenset[str] | None] = {}


def _declared_query(request: Request) -> frozenset[str] | None:
    """The query parameters the matched operation documents in the app's OpenAPI (what a client is told it may send),
    worked out once per operation; None for a route the OpenAPI leaves out."""
    route = request.scope.get("route")
    path, method = getattr(route, "path", None), request.method.lower()
    if path is None:
        return None
    if not path.startswith(PREFIX):  # the route as its own router declared it, before /v1 was put in front
        path = PREFIX + path
    if (path, method) not in _DECLARED:
        operation = request.app.openapi().get("paths", {}).get(path, {}).get(method)
        _DECLARED[(path, method)] = None if operation is None else frozenset(
            p["name"] for p in operation.get("parameters", []) if p.get("in") == "query")
    return _DECLARED[(path, method)]


def single_query_values(request: Request) -> None:
    """Every query parameter of the API is one the route declares, given once: a repeated one (?case=N1&case=N2) is
    refused with 422 naming it, instead of silently keeping the last, and so is one the route does not know
    (?clas=numeric_drift on the audit log would otherwise list every entry unfiltered)."""
    seen: set[str] = set()
    declared = _declared_query(request)
    for key, _ in request.query_params.multi_items():
        if key in seen:
            raise RequestValidationError([{"loc": ("query", key), "msg": "given more than once; give one value",
                                           "type": "value_error"}])
        if declared is not None and key not in declared:
            known = ", ".join(sorted(declared)) or "none"
            raise RequestValidationError([{"loc": ("query", key), "msg": f"unknown query parameter; this operation "
                                           f"takes: {known}", "type": "value_error"}])
        seen.add(key)


api_router = APIRouter(prefix=PREFIX, dependencies=[Depends(single_query_values)])
api_router.include_router(health.router)
api_router.include_router(submit.router)
api_router.include_router(notebooks.router)
api_router.include_router(sheets.router)
api_router.include_router(files.router)
api_router.include_router(courses.router)
api_router.include_router(assignments.router)
api_router.include_router(variants.router)
api_router.include_router(exports.router)
api_router.include_router(versions.router)
api_router.include_router(audit.router)
api_router.include_router(case_runs.router)
api_router.include_router(tokens.router)
api_router.include_router(sign_in_links.router)
api_router.include_router(registrations.router)
api_router.include_router(review_requests.router)
