"""Revoking a student's access: an instructor ends every API token and page session of a student of their course."""

from fastapi import APIRouter

from grader.api.schemas import TokensRevoked
from grader.web.deps import InstructorCourse, Name, SessionDep
from grader.api.responses import errors
from grader.services.identity import accounts

router = APIRouter(prefix="/courses", tags=["courses"], responses=errors(401, 403, 404, 422))


@router.post("/{course}/students/{name}/tokens/revoke", response_model=TokensRevoked)
def revoke_student_tokens(course: InstructorCourse, name: Name, session: SessionDep):
    """Revoke every token of a student of the course and end their page sessions at once (instructors); the student
    needs a new token (`grader admin token`, a roster import) to come back. 404 for anyone not a student here."""
    tokens, sessions = accounts.revoke_student_tokens(session=session, course=course, name=name)
    session.commit()
    return TokensRevoked(student=name, tokens_revoked=tokens, sessions_revoked=sessions)
