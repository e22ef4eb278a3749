"""Pages of the identity context (grader.services.identity): signing in and out with a token, a student's
single-use sign-in link."""

from fastapi import APIRouter

from grader.pages.identity import sign_in
from grader.pages.identity import sign_in_links

router = APIRouter(include_in_schema=False)
router.include_router(sign_in.router)
router.include_router(sign_in_links.router)

__all__ = ["router"]
