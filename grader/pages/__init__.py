"""Server-rendered pages (Jinja2 templates in grader/templates, assets in grader/static): sign-in, reports, the
class dashboard, rubrics and regrades, the audit log, an assignment's page, and a student's sign-in link and course
page. Every unsafe request to any of them is checked by origin first (grader.pages.csrf)."""

from fastapi import APIRouter, Depends

from grader.pages import (assignment, audit, dashboard, language, progress, regrade, routes, sheet_form, sign_in_links,
                          student)
from grader.pages import rubric_review
from grader.pages import lti_admin
from grader.pages import reviews
from grader.pages import setup
from grader.pages.csrf import same_origin

router = APIRouter(dependencies=[Depends(same_origin)])
router.include_router(routes.router)
router.include_router(regrade.router)
router.include_router(lti_admin.router)
router.include_router(rubric_review.router)
router.include_router(audit.router)
router.include_router(dashboard.router)
router.include_router(assignment.router)
router.include_router(sheet_form.router)
router.include_router(sign_in_links.router)
router.include_router(student.router)
router.include_router(progress.router)
router.include_router(language.router)
router.include_router(reviews.router)
router.include_router(setup.router)

__all__ = ["router"]
