"""A course: its settings (time zone), and its submissions, class dashboard, roster (with students' sign-in links) and
record of changes for its staff."""

from fastapi import APIRouter, Request

from grader.web.deps import InstructorCourse, MemberCourse, Name, SessionDep, StaffCourse, CurrentUser
from grader.api.responses import errors
from grader.api.views import submission_public
from grader.core.models import Course
from grader.core.schemas import (CoursePublic, CourseUpdate, RosterEntry, RosterImport, SignInLinkPublic,
                            SubmissionPublic)
from grader.api.schemas import CourseChangePublic, RosterStudentPublic
from grader.services.setup import course_changes, courses, roster
from grader.services.identity import sign_in_links
from grader.services.submissions import submit as submissions
from grader.services.reports.dashboard import Dashboard, course_dashboard

router = APIRouter(prefix="/courses", tags=["courses"], responses=errors(401, 403, 404, 422))


def course_public(row: Course) -> CoursePublic:
    return CoursePublic(name=row.name, timezone=row.timezone, free_submissions=row.free_submissions,
                        created_at=row.created_at)


@router.get("/{course}", response_model=CoursePublic)
def get_course(course: MemberCourse):
    """The course's settings: its time zone and whether students may submit outside assignments (anyone in the
    course)."""
    return course_public(course)


@router.patch("/{course}", response_model=CoursePublic, responses=errors(413))
def update_course(course: InstructorCourse, body: CourseUpdate, session: SessionDep, user: CurrentUser):
    """Change the course's settings (instructors): its time zone, an IANA name (times stay stored in UTC; pages and
    refusal messages show them in this zone), and whether students may submit outside assignments. An unknown zone
    is 422 naming the field, nothing changed."""
    return course_public(courses.update_settings(session=session, course=course, by=user, timezone=body.timezone,
                                                 free_submissions=body.free_submissions))


@router.get("/{course}/submissions", response_model=list[SubmissionPublic])
def course_submissions(course: StaffCourse, session: SessionDep, user: CurrentUser):
    """Every submission of a course (instructor or auditor of that course)."""
    return [submission_public(s, session, user)
            for s in submissions.visible_submissions(session=session, user=user, course=course)]


@router.get("/{course}/dashboard", response_model=Dashboard)
def dashboard(course: StaffCourse, session: SessionDep):
    """The class dashboard's data: states, failed or stuck runs (and whether each may be re-sent), roster of
    latest attempts, item analysis, predictions against measurements (H1, H4), key measurements per backend."""
    return course_dashboard(session=session, course=course)


def _link(request: Request, secret: str) -> str:
    """The page a student opens: this site's address, as the caller reached it."""
    return str(request.base_url).rstrip("/") + sign_in_links.PATH + secret


@router.get("/{course}/roster", response_model=list[RosterStudentPublic])
def list_roster(course: StaffCourse, session: SessionDep):
    """The course's students by student id, with the name and email the roster gave (instructors and auditors of the
    course; never a token or a sign-in link)."""
    return [RosterStudentPublic(student=u.name, name=u.full_name, email=u.email)
            for u in roster.students(session=session, course=course)]


@router.get("/{course}/changes", response_model=list[CourseChangePublic])
def list_changes(course: StaffCourse, session: SessionDep):
    """The course's record of set-up changes, newest first (the newest 200): settings, assignments, releases,
    extensions, roster imports and sign-in links, each with who made it and when (instructors and auditors)."""
    return [CourseChangePublic(id=c.id, at=c.at, by=c.by.name, kind=c.kind, assignment_id=c.assignment_id,
                               summary=c.summary, detail=c.detail or {})
            for c in course_changes.of_course(session=session, course=course)]


@router.post("/{course}/roster", response_model=list[RosterEntry], responses=errors(413))
def import_roster(course: InstructorCourse, body: RosterImport, session: SessionDep, request: Request,
                  user: CurrentUser):
    """Import students from CSV (student_id,name,email): new ones get a token, shown only in this answer; a student
    already there keeps their token and gets the file's name and email. With `links`, every student of the file gets
    a new single-use sign-in link (their earlier one stops working). All rows or none (instructors)."""
    entries = roster.import_csv(session=session, course=course, text=body.csv, links=body.links, by=user)
    return [RosterEntry(**{k: v for k, v in e.items() if k not in ("link_secret", "link_expires_at")},
                        sign_in_link=_link(request, e["link_secret"]) if e["link_secret"] else None,
                        sign_in_link_expires_at=e["link_expires_at"]) for e in entries]


@router.post("/{course}/students/{student}/sign-in-link", response_model=SignInLinkPublic)
def reissue_sign_in_link(course: InstructorCourse, student: Name, session: SessionDep, request: Request,
                         user: CurrentUser):
    """Issue one student of the course a new sign-in link, shown only in this answer; their earlier link stops
    working (instructors). 422 naming `student` for anyone not a student of the course."""
    secret, row = sign_in_links.issue_for(session=session, course=course, student_name=student, by=user)
    return SignInLinkPublic(student=row.user.name, sign_in_link=_link(request, secret), expires_at=row.expires_at)
