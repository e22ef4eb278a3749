"""Server-rendered pages (Jinja2 templates in grader/templates, assets in grader/static): sign-in, reports, the
class dashboard, rubrics and regrades, the audit log, and an assignment's page."""

from fastapi import APIRouter

from grader.pages import assignment, audit, dashboard, regrade, routes

router = APIRouter()
router.include_router(routes.router)
router.include_router(regrade.router)
router.include_router(audit.router)
router.include_router(dashboard.router)
router.include_router(assignment.router)

__all__ = ["router"]
