"""Pages of the rubric versions context (grader.services.rubrics): a course's versions, the tolerance review and
sign-off, the draft of a new version, the regrade preview and commit."""

from fastapi import APIRouter

from grader.pages.rubrics import tolerance_review
from grader.pages.rubrics import regrade

router = APIRouter(include_in_schema=False)
router.include_router(tolerance_review.router)
router.include_router(regrade.router)

__all__ = ["router"]
