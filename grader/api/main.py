"""Collects the routers under /v1."""

from fastapi import APIRouter, Depends, Request
from fastapi.exceptions import RequestValidationError

from grader.api.routes import reviews
from grader.api.routes import (assignments, audit, case_runs, courses, exports, files, health, lti, rubrics,
                               submissions, tokens)


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
api_router.include_router(submissions.router)
api_router.include_router(files.router)
api_router.include_router(courses.router)
api_router.include_router(assignments.router)
api_router.include_router(exports.router)
api_router.include_router(rubrics.router)
api_router.include_router(audit.router)
api_router.include_router(case_runs.router)
api_router.include_router(tokens.router)
api_router.include_router(lti.router)
api_router.include_router(reviews.router)
