"""Server-rendered pages (Jinja2 templates in grader/templates, assets in grader/static): sign-in and reports."""

from fastapi import APIRouter

from grader.pages import audit, dashboard, regrade, routes

router = APIRouter()
router.include_router(routes.router)
router.include_router(regrade.router)
router.include_router(audit.router)
router.include_router(dashboard.router)

__all__ = ["router"]
