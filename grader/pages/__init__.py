"""Server-rendered pages (Jinja2 templates in grader/templates, assets in grader/static): sign-in, reports, the
class dashboard, rubrics and regrades, the audit log, and an assignment's page. Every unsafe request to any of them
is checked by origin first (grader.pages.csrf)."""

from fastapi import APIRouter, Depends

from grader.pages import assignment, audit, dashboard, regrade, routes
from grader.pages.csrf import same_origin

router = APIRouter(dependencies=[Depends(same_origin)])
router.include_router(routes.router)
router.include_router(regrade.router)
router.include_router(audit.router)
router.include_router(dashboard.router)
router.include_router(assignment.router)

__all__ = ["router"]
