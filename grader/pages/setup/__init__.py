"""Pages of the course set-up context (grader.services.setup): the set-up page (time zone, roster, sign-in
links, the assignment form) and an instructor's assignment page (release, extensions, grades)."""

from fastapi import APIRouter

from grader.pages.setup import courses
from grader.pages.setup import assignments

router = APIRouter(include_in_schema=False)
router.include_router(courses.router)
router.include_router(assignments.router)

__all__ = ["router"]
