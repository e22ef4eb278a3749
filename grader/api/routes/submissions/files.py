"""Downloads: a case run's evidence files (arrays .npz, provenance, captured output) and the measured series the
report's charts draw; both from the database, so any API host serves them."""

from __future__ import annotations

from typing import Literal

from fastapi import APIRouter, HTTPException, status
from fastapi.responses import Response

from grader.web.deps import CurrentUser, Name, SessionDep, SubmissionDep
from grader.api.responses import errors, file_ok
from grader.services.reports.exports import EVIDENCE
from grader.services.reports import exports, series as chart_series
from grader.core.states import SubmissionState
from grader.services.submissions.visibility import grade_view

router = APIRouter(prefix="/submissions/{submission_id}", tags=["files"], responses=errors(401, 404, 422))
# A file route only ever names a file by one of these shapes, so no path (.., /, NUL) reaches the filesystem.
EvidenceName = Literal[tuple(EVIDENCE)]


@router.get("/case-runs/{name}/files/{filename}", response_class=Response,
            responses={**file_ok("The file", *sorted(set(EVIDENCE.values()))), **errors(409, _409=(
                "The run's measurements decide an item withheld from the caller: shown with that item"))})
def case_run_file(submission: SubmissionDep, name: Name, filename: EvidenceName, session: SessionDep,
                  user: CurrentUser):
    """One evidence file of a case run (arrays.npz, provenance.json, metrics.json, spec.json, stdout, stderr); 409
    for a run whose measurements decide an item withheld from the caller."""
    withheld = grade_view(session=session, submission=submission, user=user, report=False).withheld_runs
    body, media_type = exports.evidence_file(submission=submission, name=name, filename=filename, withheld=withheld)
    return Response(body, media_type=media_type, headers={
        "Content-Disposition": f'attachment; filename="{submission.id}-{name}-{filename}"'})


@router.get("/series", responses=errors(409, _409="Not graded yet"))
def series(submission: SubmissionDep, session: SessionDep, user: CurrentUser) -> dict:
    """The measured series of every case run (time, heights, velocities, lanes' displacements), as the report's
    charts draw them: measurements only, no item's score or verdict, and none of a run that decides an item withheld
    from the caller (named under `withheld`)."""
    if submission.status != SubmissionState.GRADED:
        raise HTTPException(status.HTTP_409_CONFLICT, f"submission {submission.id} is {submission.status}")
    withheld = grade_view(session=session, submission=submission, user=user, report=False).withheld_runs
    return chart_series.submission_series(submission=submission, withheld=withheld)
