"""Rubric versions (list, publish) and a course's regrades (preview, commit, history), for its instructors.

Publishing and committing are instructor-only and recorded with who and when; auditors may read both. A published
version belongs to its publisher's course: no other course lists, previews or commits it.
"""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import APIRouter, Body, HTTPException, Path, Query, status
from pydantic import ValidationError
from sqlalchemy.exc import IntegrityError

from grader.api.schemas import RegradeRequest, RubricVersionPublic
from grader.web.deps import CurrentUser, SessionDep, StaffCourse, StaffUser
from grader.web.errors import error
from grader.api.responses import errors
from grader.core import rubrics as store
from grader.core.models import RubricVersion
from grader.services.identity import access
from grader.services.errors import field_errors
from grader.services.rubrics.regrade import (
    LESSON_PATTERN,
    RegradePreview,
    RegradeRecord,
    commit_regrade,
    preview_regrade,
    record,
    regrade_records,
    rubric_versions,
)
from rubric.governance import RubricGovernanceError
from rubric.rubrics import VERSION_PATTERN
from rubric.specs import describe_errors

LESSON, VERSION = LESSON_PATTERN, VERSION_PATTERN
CONFLICT = errors(409, _409="Refused by rubric governance, an archived version, content other than the preview's, "
                             "or a concurrent regrade")
router = APIRouter(tags=["rubrics"], responses=errors(401, 403, 422))


def _public(row: RubricVersion) -> RubricVersionPublic:
    return RubricVersionPublic(lesson=row.lesson, version=row.version, content_hash=row.content_hash,
                               source=row.source, published_by=row.published_by.name if row.published_by else None,
                               published_at=row.published_at, review=row.content.get("review", {}))


@router.get("/rubrics/{lesson}/versions", response_model=list[RubricVersionPublic])
def list_versions(lesson: Annotated[str, Path(pattern=LESSON)], session: SessionDep, user: StaffUser):
    """The rubric versions of a lesson the caller's course may use, oldest first: shipped with the service or published
    by the course's instructors (staff)."""
    return [_public(r) for r in rubric_versions(session, course=user.course, lesson=lesson)]


@router.post("/rubrics/versions", response_model=RubricVersionPublic, status_code=status.HTTP_201_CREATED,
             responses={**errors(413), **CONFLICT})
def publish(session: SessionDep, user: CurrentUser, content: Annotated[dict[str, Any], Body()]):
    """Publish a rubric version for the caller's course (the same fields as a rubric/lessons YAML file, as JSON).
    A published version never changes: other content under a version the course published or the service ships is
    refused (409), as is a changed tolerance without a new review record; identical content answers the stored one."""

    access.require_instructor(user, action="publish rubric versions")
    try:
        row = store.publish(session, content=content, user=user)
        session.commit()
    except ValidationError as exc:
        return error(422, "invalid rubric", field_errors(describe_errors(exc)))
    except RubricGovernanceError as exc:
        raise HTTPException(status.HTTP_409_CONFLICT, str(exc)) from exc
    except IntegrityError as exc:  # the same version published at the same moment by another instructor
        session.rollback()
        raise HTTPException(status.HTTP_409_CONFLICT, "this version was published at the same time; list the "
                                                      "versions and publish again if it differs") from exc
    return _public(row)


@router.get("/courses/{course}/regrade-preview", response_model=RegradePreview,
            responses={**errors(404), **CONFLICT})
def regrade_preview(row: StaffCourse, session: SessionDep,
                    version: Annotated[str, Query(pattern=VERSION, max_length=32)],
                    lesson: Annotated[str, Query(pattern=LESSON)] = "L03"):
    """Per student, the old and new totals and each item that changes and why, and the content_hash a commit names;
    nothing is written."""
    return preview_regrade(session, course=row, lesson=lesson, version=version)


@router.post("/courses/{course}/regrades", response_model=RegradeRecord, status_code=status.HTTP_201_CREATED,
             responses={**errors(404, 413), **CONFLICT})
def regrade_commit(row: StaffCourse, request: RegradeRequest, session: SessionDep, user: CurrentUser):
    """Regrade the course's lesson under the version whose content_hash the preview showed, keeping the old grades;
    later submissions use it too."""

    access.require_instructor(user, action="commit a regrade")
    regrade, _ = commit_regrade(session, course=row, lesson=request.lesson, version=request.version,
                                content_hash=request.content_hash, user=user)
    return record(regrade, row)


@router.get("/courses/{course}/regrades", response_model=list[RegradeRecord], responses=errors(404))
def regrades(row: StaffCourse, session: SessionDep):
    """Every committed regrade of the course, newest first, with who committed it and when."""
    return regrade_records(session, course=row)
