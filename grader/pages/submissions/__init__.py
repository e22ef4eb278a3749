"""Pages of the submissions context (grader.services.submissions): the sheet form and its confirmation, the
progress page, the list and the report, overrides and review requests."""

from fastapi import APIRouter

from grader.pages.submissions import report
from grader.pages.submissions import sheet_form
from grader.pages.submissions import notebooks
from grader.pages.submissions import progress
from grader.pages.submissions import review_requests

router = APIRouter(include_in_schema=False)
router.include_router(report.router)
router.include_router(sheet_form.router)
router.include_router(notebooks.router)
router.include_router(progress.router)
router.include_router(review_requests.router)

__all__ = ["router"]
