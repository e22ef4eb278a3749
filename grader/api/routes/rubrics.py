"""Rubric versions (list, publish) and a course's regrades (preview, commit, history), for its instructors.

Publishing and committing are instructor-only and recorded with who and when; auditors may read both.
"""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import APIRouter, Body, HTTPException, Path, Query, status
from pydantic import BaseModel, ConfigDict, Field, ValidationError
from sqlalchemy.exc import IntegrityError

from grader.api.deps import CurrentUser, SessionDep, StaffCourse, StaffUser
from grader.api.errors import error
from grader.api.responses import errors
from grader.core import rubrics as store
from grader.models import RubricVersion
from grader.schemas import UtcDateTime
from grader.services import access
from grader.services.errors import field_errors
from grader.services.regrade import (
    RegradePreview,
    RegradeRecord,
    commit_regrade,
    preview_regrade,
    record,
    regrade_records,
    rubric_versions,
)
from rubric import ArchivedRubric
from rubric.governance import RubricGovernanceError
from rubric.specs import describe_errors

LESSON = r"^L[0-9]{2}$"
VERSION = r"^[0-9]+(\.[0-9]+)*$"
CONFLICT = errors(409, _409="Refused by rubric governance, an archived version, or a concurrent regrade")
router = APIRouter(tags=["rubrics"], responses=errors(401, 403, 422))


class RubricVersionPublic(BaseModel):
    lesson: str
    version: str
    content_hash: str
    source: str
    published_by: str | None
    published_at: UtcDateTime
    review: dict[str, Any]


class RegradeRequest(BaseModel):
    model_config = ConfigDict(extra="forbid")

    lesson: Annotated[str, Field(pattern=LESSON)] = "L03"
    version: Annotated[str, Field(pattern=VERSION, max_length=32)]


def _public(row: RubricVersion) -> RubricVersionPublic:
    return RubricVersionPublic(lesson=row.lesson, version=row.version, content_hash=row.content_hash,
                               source=row.source, published_by=row.published_by.name if row.published_by else None,
                               published_at=row.published_at, review=row.content.get("review", {}))


@router.get("/rubrics/{lesson}/versions", response_model=list[RubricVersionPublic])
def list_versions(lesson: Annotated[str, Path(pattern=LESSON)], session: SessionDep, user: StaffUser):
    """Every rubric version of a lesson the service knows, oldest first: shipped with it or published (staff)."""
    return [_public(r) for r in rubric_versions(session, lesson)]


@router.post("/rubrics/versions", response_model=RubricVersionPublic, status_code=status.HTTP_201_CREATED,
             responses={**errors(413), **CONFLICT})
def publish(session: SessionDep, user: CurrentUser, content: Annotated[dict[str, Any], Body()]):
    """Publish a rubric version (the same fields as a rubric/lessons YAML file, as JSON). Governance refuses a
    change to a version any grade used and a changed tolerance without a new review record (409)."""

    access.require_instructor(user, action="publish rubric versions")
    try:
        row = store.publish(session, content=content, user=user)
    except ValidationError as exc:
        return error(422, "invalid rubric", field_errors(describe_errors(exc)))
    except RubricGovernanceError as exc:
        raise HTTPException(status.HTTP_409_CONFLICT, str(exc)) from exc
    session.commit()
    return _public(row)


def _version_or_404(session, lesson: str, version: str):
    try:
        return store.get_version(session, lesson, version)
    except LookupError as exc:
        raise HTTPException(status.HTTP_404_NOT_FOUND, str(exc)) from exc


@router.get("/courses/{course}/regrade-preview", response_model=RegradePreview,
            responses={**errors(404), **CONFLICT})
def regrade_preview(row: StaffCourse, session: SessionDep,
                    version: Annotated[str, Query(pattern=VERSION, max_length=32)],
                    lesson: Annotated[str, Query(pattern=LESSON)] = "L03"):
    """Per student, the old and new totals and each item that changes and why; nothing is written."""

    _version_or_404(session, lesson, version)
    try:
        return preview_regrade(session, course=row, lesson=lesson, version=version)
    except ArchivedRubric as exc:
        raise HTTPException(status.HTTP_409_CONFLICT, str(exc)) from exc


@router.post("/courses/{course}/regrades", response_model=RegradeRecord, status_code=status.HTTP_201_CREATED,
             responses={**errors(404, 413), **CONFLICT})
def regrade_commit(row: StaffCourse, request: RegradeRequest, session: SessionDep, user: CurrentUser):
    """Regrade the course's lesson under the version and keep the old grades; later submissions use it too."""

    access.require_instructor(user, action="commit a regrade")
    _version_or_404(session, request.lesson, request.version)
    try:
        regrade, _ = commit_regrade(session, course=row, lesson=request.lesson, version=request.version, user=user)
    except ArchivedRubric as exc:
        raise HTTPException(status.HTTP_409_CONFLICT, str(exc)) from exc
    except IntegrityError as exc:
        session.rollback()
        raise HTTPException(status.HTTP_409_CONFLICT, "another regrade of this course committed at the same time; "
                                                      "preview again") from exc
    return record(regrade, row)


@router.get("/courses/{course}/regrades", response_model=list[RegradeRecord], responses=errors(404))
def regrades(row: StaffCourse, session: SessionDep):
    """Every committed regrade of the course, newest first, with who committed it and when."""
    return regrade_records(session, course=row)
