"""Downloads: a case run's evidence files (arrays .npz, provenance, captured output; from the database) and the lab
figures."""

from __future__ import annotations

from typing import Annotated, Literal

from fastapi import APIRouter, HTTPException, Path, status
from fastapi.responses import FileResponse, Response

from grader.api.deps import Name, SubmissionDep
from grader.api.responses import errors, file_ok
from grader.services.exports import EVIDENCE
from grader.services import exports
from grader.settings import settings
from grader.core.states import SubmissionState

router = APIRouter(prefix="/submissions/{submission_id}", tags=["files"], responses=errors(401, 404, 422))
# A file route only ever names a file by one of these shapes, so no path (.., /, NUL) reaches the filesystem.
EvidenceName = Literal[tuple(EVIDENCE)]
FigureName = Annotated[str, Path(pattern=r"^[A-Za-z0-9_][A-Za-z0-9_.-]{0,250}\.png$",
                                 description="A figure's file name as listed by ../figures")]


@router.get("/case-runs/{name}/files/{filename}", response_class=Response,
            responses=file_ok("The file", *sorted(set(EVIDENCE.values()))))
def case_run_file(submission: SubmissionDep, name: Name, filename: EvidenceName):
    """One evidence file of a case run (arrays.npz, provenance.json, metrics.json, spec.json, stdout, stderr)."""
    body, media_type = exports.evidence_file(submission=submission, name=name, filename=filename)
    return Response(body, media_type=media_type, headers={
        "Content-Disposition": f'attachment; filename="{submission.id}-{name}-{filename}"'})


@router.get("/figures", response_model=list[str], responses=errors(409, _409="Not graded yet"))
def list_figures(submission: SubmissionDep) -> list[str]:
    """Names of the lab figures the worker drew from this submission's measurements when it graded it."""
    if submission.status != SubmissionState.GRADED:
        raise HTTPException(status.HTTP_409_CONFLICT, f"submission {submission.id} is {submission.status}")
    folder = settings.figures_dir(submission.id)
    return sorted(p.name for p in folder.glob("*.png")) if folder.is_dir() else []


@router.get("/figures/{filename}", response_class=FileResponse, responses=file_ok("The PNG figure", "image/png"))
def figure(submission: SubmissionDep, filename: FigureName):
    """One lab figure (PNG)."""
    path = settings.figures_dir(submission.id) / filename
    if not path.is_file():
        raise HTTPException(status.HTTP_404_NOT_FOUND, f"no figure {filename!r}; list them at ../figures")
    return FileResponse(path, media_type="image/png")
