"""Collects the routers under /v1."""

from fastapi import APIRouter

from grader.api.routes import assignments, audit, case_runs, courses, exports, files, health, rubrics, submissions

api_router = APIRouter(prefix="/v1")
api_router.include_router(health.router)
api_router.include_router(submissions.router)
api_router.include_router(files.router)
api_router.include_router(courses.router)
api_router.include_router(assignments.router)
api_router.include_router(exports.router)
api_router.include_router(rubrics.router)
api_router.include_router(audit.router)
api_router.include_router(case_runs.router)
