"""A course's submissions, for its instructors and auditors."""

from fastapi import APIRouter, HTTPException, status
from sqlalchemy import select

from grader import crud
from grader.api.deps import CurrentUser, SessionDep
from grader.api.responses import AUTH, FORBIDDEN, NOT_FOUND
from grader.api.views import submission_public
from grader.models import Course
from grader.schemas import SubmissionPublic

router = APIRouter(prefix="/courses", tags=["courses"], responses={**AUTH, **FORBIDDEN, **NOT_FOUND})


@router.get("/{course}/submissions", response_model=list[SubmissionPublic])
def course_submissions(course: str, session: SessionDep, user: CurrentUser):
    """Every submission of a course (instructor or auditor of that course)."""
    row = session.scalar(select(Course).where(Course.name == course))
    if row is None or row.id != user.course_id:
        raise HTTPException(status.HTTP_404_NOT_FOUND, f"course {course!r} not found")
    if user.role == "student":
        raise HTTPException(status.HTTP_403_FORBIDDEN, "students see only their own submissions")
    return [submission_public(s, session) for s in crud.visible_submissions(session=session, user=user, course=row)]
