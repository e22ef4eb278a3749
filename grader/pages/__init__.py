"""The server-rendered pages, one package per service context (grader/services/<context>, templates/<context>),
plus what every page shares: who is signed in (auth), the origin check (csrf), refusals (errors), the Jinja
environment (templates), view models (views) and the language switch. Every unsafe request to any of them is checked
by origin first (grader.pages.csrf)."""

from fastapi import APIRouter, Depends

from grader.pages import identity, language, lti, reports, rubrics, setup, submissions
from grader.pages.csrf import same_origin

router = APIRouter(dependencies=[Depends(same_origin)])
for context in (identity, setup, submissions, rubrics, reports, lti):
    router.include_router(context.router)
router.include_router(language.router)

__all__ = ["router"]
