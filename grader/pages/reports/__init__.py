"""Pages of the read models (grader.services.reports): a student's course page, the class dashboard, the audit log,
the instructors' downloads."""

from fastapi import APIRouter

from grader.pages.reports import course_page
from grader.pages.reports import dashboard
from grader.pages.reports import audit
from grader.pages.reports import exports

router = APIRouter(include_in_schema=False)
router.include_router(course_page.router)
router.include_router(dashboard.router)
router.include_router(audit.router)
router.include_router(exports.router)

__all__ = ["router"]
