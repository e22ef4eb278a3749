"""Collects the routers under /v1: one package per service context (grader/services/<context>), health apart."""

from fastapi import APIRouter, Depends, Request
from fastapi.exceptions import RequestValidationError

from grader.api.routes import health
from grader.api.routes.identity import tokens
from grader.api.routes.lti import registrations
from grader.api.routes.reports import audit, exports
from grader.api.routes.rubrics import versions
from grader.api.routes.setup import assignments, courses, variants
from grader.api.routes.submissions import case_runs, files, review_requests, submit


def single_query_values(request: Request) -> None:
    """Every query parameter of the API is one value: a repeated one (?case=N1&case=N2) is refused with 422 naming
    it, instead of silently keeping the last."""
    seen: set[str] = set()
    for key, _ in request.query_params.multi_items():
        if key in seen:
            raise RequestValidationError([{"loc": ("query", key), "msg": "given more than once; give one value",
                                           "type": "value_error"}])
        seen.add(key)


api_router = APIRouter(prefix="/v1", dependencies=[Depends(single_query_values)])
api_router.include_router(health.router)
api_router.include_router(submit.router)
api_router.include_router(files.router)
api_router.include_router(courses.router)
api_router.include_router(assignments.router)
api_router.include_router(variants.router)
api_router.include_router(exports.router)
api_router.include_router(versions.router)
api_router.include_router(audit.router)
api_router.include_router(case_runs.router)
api_router.include_router(tokens.router)
api_router.include_router(registrations.router)
api_router.include_router(review_requests.router)
