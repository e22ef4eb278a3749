"""Downloads: a case run's evidence files (arrays .npz, provenance, captured output) and the lab figures."""

from __future__ import annotations

from pathlib import Path

from fastapi import APIRouter, HTTPException, status
from fastapi.responses import FileResponse

from grader.api.deps import SubmissionDep
from grader.api.responses import NOT_FOUND
from grader.settings import settings

router = APIRouter(prefix="/submissions/{submission_id}", tags=["files"], responses=NOT_FOUND)
EVIDENCE = {"arrays.npz": "application/octet-stream", "provenance.json": "application/json",
            "metrics.json": "application/json",
            "spec.json": "application/json", "stdout.txt": "text/plain", "stderr.txt": "text/plain"}


@router.get("/case-runs/{name}/files/{filename}", response_class=FileResponse)
def case_run_file(submission: SubmissionDep, name: str, filename: str):
    """One evidence file of a case run (arrays.npz, provenance.json, metrics.json, spec.json, stdout, stderr)."""
    run = next((r for r in submission.case_runs if r.name == name), None)
    if run is None or filename not in EVIDENCE or not run.artifact_dir:
        raise HTTPException(status.HTTP_404_NOT_FOUND, f"no file {filename!r} for case run {name!r}")
    path = Path(run.artifact_dir) / filename
    if not path.is_file():
        raise HTTPException(status.HTTP_404_NOT_FOUND, f"{filename} was not written by case run {name!r}")
    return FileResponse(path, media_type=EVIDENCE[filename], filename=f"{submission.id}-{name}-{filename}")


@router.get("/figures", response_model=list[str], responses={409: {"description": "Not graded yet"}})
def list_figures(submission: SubmissionDep) -> list[str]:
    """Names of the lab figures the worker drew from this submission's measurements when it graded it."""
    if submission.status != "graded":
        raise HTTPException(status.HTTP_409_CONFLICT, f"submission {submission.id} is {submission.status}")
    folder = settings.figures_dir(submission.id)
    return sorted(p.name for p in folder.glob("*.png")) if folder.is_dir() else []


@router.get("/figures/{filename}", response_class=FileResponse)
def figure(submission: SubmissionDep, filename: str):
    """One lab figure (PNG)."""
    path = settings.figures_dir(submission.id) / filename
    if "/" in filename or not filename.endswith(".png") or not path.is_file():
        raise HTTPException(status.HTTP_404_NOT_FOUND, f"no figure {filename!r}; list them at ../figures")
    return FileResponse(path, media_type="image/png")
