"""Pages of the LMS context (grader.services.lti): the launch, deep linking and keys (grader.pages.lti.launch, mounted
by grader.main outside the pages' origin check: a platform posts them) and the instructor's outbox page."""

from fastapi import APIRouter

from grader.pages.lti import outbox

router = APIRouter(include_in_schema=False)
router.include_router(outbox.router)

__all__ = ["router"]
