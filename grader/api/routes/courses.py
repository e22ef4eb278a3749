"""A course: its settings (time zone), and its submissions, class dashboard and roster for its staff."""

from fastapi import APIRouter, HTTPException, status
from sqlalchemy import select

from grader import crud, roster
from grader.timezones import is_zone
from grader.api.errors import FieldError
from grader.api.deps import CurrentUser, Name, SessionDep
from grader.api.responses import errors
from grader.api.views import submission_public
from grader.models import Course
from grader.dashboard import Dashboard, course_dashboard
from grader.schemas import CoursePublic, CourseUpdate, RosterEntry, RosterImport, SubmissionPublic

router = APIRouter(prefix="/courses", tags=["courses"], responses=errors(401, 403, 404, 422))


def staff_course(course: str, session, user) -> Course:
    """The caller's own course, for its instructors and auditors; 404 for another course, 403 for a student."""
    row = session.scalar(select(Course).where(Course.name == course))
    if row is None or row.id != user.course_id:
        raise HTTPException(status.HTTP_404_NOT_FOUND, f"course {course!r} not found")
    if user.role == "student":
        raise HTTPException(status.HTTP_403_FORBIDDEN, "students see only their own submissions")
    return row


def member_course(course: str, session, user) -> Course:
    """The caller's own course; any other is 404, whether or not it exists."""
    row = session.scalar(select(Course).where(Course.name == course))
    if row is None or row.id != user.course_id:
        raise HTTPException(status.HTTP_404_NOT_FOUND, f"course {course!r} not found")
    return row


def course_public(row: Course) -> CoursePublic:
    return CoursePublic(name=row.name, timezone=row.timezone, created_at=row.created_at)


@router.get("/{course}", response_model=CoursePublic)
def get_course(course: Name, session: SessionDep, user: CurrentUser):
    """The course's settings: its time zone (anyone in the course)."""
    return course_public(member_course(course, session, user))


@router.patch("/{course}", response_model=CoursePublic, responses=errors(413))
def update_course(course: Name, body: CourseUpdate, session: SessionDep, user: CurrentUser):
    """Set the course's time zone, an IANA name (instructors). Times stay stored in UTC; pages and refusal messages
    show them in this zone. An unknown zone is 422 naming the field."""
    row = member_course(course, session, user)
    if user.role != "instructor":
        raise HTTPException(status.HTTP_403_FORBIDDEN, "only instructors change a course's settings")
    if not is_zone(body.timezone):
        raise FieldError(422, "invalid course settings", [{"field": "timezone", "rule": (
            f"{body.timezone!r} is not an IANA time zone name (e.g. UTC, Europe/Berlin, America/New_York)")}])
    row.timezone = body.timezone
    session.commit()
    return course_public(row)


@router.get("/{course}/submissions", response_model=list[SubmissionPublic])
def course_submissions(course: Name, session: SessionDep, user: CurrentUser):
    """Every submission of a course (instructor or auditor of that course)."""
    row = staff_course(course, session, user)
    return [submission_public(s, session) for s in crud.visible_submissions(session=session, user=user, course=row)]


@router.get("/{course}/dashboard", response_model=Dashboard)
def dashboard(course: Name, session: SessionDep, user: CurrentUser):
    """The class dashboard's data: states, failed or stuck runs (and whether each may be re-sent), roster of
    latest attempts, item analysis, predictions against measurements (H1, H4), key measurements per backend."""
    return course_dashboard(session=session, course=staff_course(course, session, user))


@router.post("/{course}/roster", response_model=list[RosterEntry], responses=errors(413))
def import_roster(course: Name, body: RosterImport, session: SessionDep, user: CurrentUser):
    """Import students from CSV (student_id,name,email): new ones get a token, shown only in this answer; a student
    already there keeps their token and gets the file's name and email. All rows or none (instructors)."""
    row = staff_course(course, session, user)
    if user.role != "instructor":
        raise HTTPException(status.HTTP_403_FORBIDDEN, "only instructors import a roster")
    rows, problems = roster.parse_roster(body.csv)
    problems = problems or roster.role_conflicts(session=session, course=row, rows=rows)
    if problems:
        raise FieldError(422, "invalid roster", problems)
    entries = roster.import_roster(session=session, course=row, rows=rows)
    session.commit()
    return entries
