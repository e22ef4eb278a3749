"""A course's LTI 1.3 platform registrations, created and listed by its instructors (operators use `grader lti`), an
assignment's counted scores sent to the LMS gradebooks, and the roster synced from the LMS."""

from __future__ import annotations


from fastapi import APIRouter, Request, status

from grader.api.schemas import LtiRegistrationCreate, LtiRegistrationPublic, RosterSyncPublic, ScoreSentPublic
from grader.web.deps import CurrentUser, InstructorCourse, SessionDep
from grader.api.responses import errors
from grader.core.models import LtiRegistration
from grader.services.setup import assignments
from grader.services.lti import launch as lti
from grader.services.lti import roster

router = APIRouter(prefix="/courses/{course}/lti", tags=["lti"], responses=errors(401, 403, 404, 422))


def registration_public(row: LtiRegistration) -> LtiRegistrationPublic:
    return LtiRegistrationPublic(id=row.id, course=row.course.name, issuer=row.issuer, client_id=row.client_id,
                                 deployment_ids=[d.deployment_id for d in row.deployments],
                                 auth_login_url=row.auth_login_url, auth_token_url=row.auth_token_url,
                                 key_set_url=row.key_set_url, created_at=row.created_at)


@router.post("/registrations", response_model=LtiRegistrationPublic, status_code=status.HTTP_201_CREATED,
             responses=errors(409, 413))
def create_registration(course: InstructorCourse, body: LtiRegistrationCreate, session: SessionDep,
                        user: CurrentUser):
    """Register a platform for the course (instructors). A bad URL or empty id is 422 naming the field; an issuer
    and client id already registered is 409."""
    row = lti.create_registration(session=session, course=course, by=user, **body.model_dump())
    session.commit()
    return registration_public(row)


@router.get("/registrations", response_model=list[LtiRegistrationPublic])
def list_registrations(course: InstructorCourse, session: SessionDep):
    """The course's platform registrations (instructors)."""
    return [registration_public(row) for row in lti.course_registrations(session=session, course=course)]


@router.post("/assignments/{assignment_id}/scores", response_model=list[ScoreSentPublic])
def send_scores(course: InstructorCourse, assignment_id: int, request: Request, session: SessionDep,
                user: CurrentUser):
    """Send the assignment's counted scores to the LMS gradebooks (instructors): only changed or failed ones go;
    a failure is listed with its error and tried again on the next call."""
    assignment = assignments.assignment_of(session=session, user=user, assignment_id=assignment_id)
    sent = lti.send_scores(session=session, assignment=assignment,
                           report_url=str(request.base_url).rstrip("/") + "/submissions/{id}")
    session.commit()
    return [ScoreSentPublic(**vars(s)) for s in sent]


@router.post("/roster-sync", response_model=RosterSyncPublic, responses=errors(409))
def sync_roster(course: InstructorCourse, session: SessionDep):
    """Sync the course's students from its LMS courses' rosters (instructors): added, updated and dropped students
    are listed; nobody is duplicated and nobody deleted. 409 when no LMS course offered its roster, a page could not
    be read or the roster passed LTI_ROSTER_MAX_MEMBERS (the pages read before are kept, as the 409 says)."""
    result = roster.sync_roster(session=session, course=course)
    session.commit()
    return RosterSyncPublic(**vars(result))
