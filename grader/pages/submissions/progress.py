"""A submission's progress page, where the form leads after submitting (grader.services.submissions.progress): its runs' places
in their queues, the estimate from measured case durations, each run's state, then the report. Its script polls the
JSON beside it; without a script the page refreshes itself. Only who may read the submission sees it."""

from __future__ import annotations

from fastapi import APIRouter, Request, status
from fastapi.responses import HTMLResponse, JSONResponse

from grader.web.deps import SessionDep
from grader.pages.auth import SignedIn
from grader.pages.templates import TEMPLATES
from grader.services.submissions import progress as logic
from grader.services.errors import NotFound

router = APIRouter(include_in_schema=False)
POLL_MS = 1500  # how often the page's script asks; the page without a script refreshes every NO_SCRIPT_REFRESH_S
NO_SCRIPT_REFRESH_S = 3


def _context(request: Request, user, progress: logic.Progress) -> dict:
    return {"user": user, "p": progress, "s": progress.submission, "poll_ms": POLL_MS,
            "refresh_s": NO_SCRIPT_REFRESH_S}


@router.get("/submissions/{submission_id}/progress", response_class=HTMLResponse)
def progress_page(request: Request, submission_id: int, session: SessionDep, user: SignedIn):
    """Where the submission's case runs are, live; NotFound (the not-found page) for one the caller may not read."""
    progress = logic.submission_progress(session=session, user=user, submission_id=submission_id)
    return TEMPLATES.TemplateResponse(request, "submissions/progress.html", _context(request, user, progress))


@router.get("/submissions/{submission_id}/progress.json")
def progress_json(request: Request, submission_id: int, session: SessionDep, user: SignedIn):
    """What the page's script polls: the states as data, and the live part of the page rendered as the page has it."""
    try:
        progress = logic.submission_progress(session=session, user=user, submission_id=submission_id)
    except NotFound as exc:
        return JSONResponse({"detail": exc.detail}, status_code=status.HTTP_404_NOT_FOUND)
    # rendered like any page (same environment and context), so the polled part reads as the page it replaces
    live = TEMPLATES.TemplateResponse(request, "submissions/_progress_live.html", _context(request, user, progress)).body.decode()
    return JSONResponse(logic.as_json(progress) | {"html": live}, headers={"Cache-Control": "no-store"})
