"""Roles checked in the set-up services themselves (issue 31), not only by the page and API dependencies in front of
them: every change a set-up service makes (assignments created and edited, extensions granted and revoked, a release,
the course's time zone and settings) refuses a student and an auditor (a TA) of the course with Forbidden and anyone
outside it with NotFound, storing and recording nothing. Shown by calling the services directly, and through the
real app with one web dependency loosened to admit staff: the service still refuses the TA."""

from __future__ import annotations

from datetime import timedelta

import pytest
from sqlalchemy import func, select

from grader.web.deps import MemberCourse, SessionDep
from grader.core.db import new_session
from grader.pages.auth import SignedIn
from grader.core.models import Assignment, Course, CourseChange, Extension, User, utcnow
from grader.services.setup import assignments, courses
from grader.services.errors import Forbidden, NotFound
from tests.grader.services.setup.test_assignments import create
from tests.grader.pages.test_setup_pages import BERLIN_FORM, page_post


def _user(session, name: str) -> User:
    return session.scalar(select(User).where(User.name == name))


def _state() -> tuple:
    """Everything a set-up change could touch: the course's settings, assignments, extensions and change records."""
    with new_session() as session:
        course = session.scalar(select(Course).where(Course.name == "l03"))
        rows = [(a.id, a.title, a.released_at, a.max_attempts) for a in session.scalars(select(Assignment))]
        return (course.timezone, course.free_submissions, rows,
                session.scalar(select(func.count()).select_from(Extension)),
                session.scalar(select(func.count()).select_from(CourseChange)))


def _fields(**over) -> dict:
    """A whole assignment's settings as the service takes them (validated as the API validates its body)."""
    now = utcnow()
    return assignments.checked({"title": "Week 3", "lesson": "L03", "part": "checkpoints",
                                "open_at": f"{(now - timedelta(days=1)).isoformat()}Z",
                                "due_at": f"{(now + timedelta(days=1)).isoformat()}Z",
                                "hard_close_at": f"{(now + timedelta(days=2)).isoformat()}Z", **over})


CHANGES = {
    "time zone": lambda s, a, u: courses.update_settings(session=s, course=a.course, by=u, timezone="Europe/Berlin"),
    "free submissions": lambda s, a, u: courses.update_settings(session=s, course=a.course, by=u,
                                                                free_submissions=False),
    "create": lambda s, a, u: assignments.create(session=s, course=a.course, user=u, fields=_fields()),
    "edit": lambda s, a, u: assignments.update(session=s, assignment=a, by=u, fields=_fields(title="Renamed")),
    "release": lambda s, a, u: assignments.release(session=s, assignment=a, by=u),
    "grant": lambda s, a, u: assignments.grant_extension(session=s, assignment=a, student_name="bob",
                                                         due_at=utcnow() + timedelta(days=5),
                                                         hard_close_at=utcnow() + timedelta(days=6), user=u),
    "revoke": lambda s, a, u: assignments.revoke_extension(session=s, assignment=a, student_name="alice", by=u),
}


@pytest.mark.parametrize("change", sorted(CHANGES))
@pytest.mark.parametrize("who, refusal", [("tess", Forbidden), ("alice", Forbidden), ("eve", NotFound)])
def test_each_setup_service_refuses_who_may_not_change_the_course_and_stores_nothing(api, change, who, refusal):
    aid = create(api).json()["id"]
    granted = api.client.post(f"/v1/assignments/{aid}/extensions", headers=api.as_("prof"), json={
        "student": "alice", "due_at": (utcnow() + timedelta(days=3)).isoformat() + "Z",
        "hard_close_at": (utcnow() + timedelta(days=4)).isoformat() + "Z"})
    assert granted.status_code == 201, granted.text  # so that a revoke has something to take away
    before = _state()
    with new_session() as session:
        assignment = session.get(Assignment, aid)
        with pytest.raises(refusal) as refused:
            CHANGES[change](session, assignment, _user(session, who))
        session.rollback()
    if refusal is Forbidden:
        assert "only instructors may" in refused.value.detail and who in refused.value.detail
    else:
        assert refused.value.detail.endswith("not found")  # another course's instructor learns nothing more
    assert _state() == before
    # The course's instructor may make the same change through the same service.
    with new_session() as session:
        CHANGES[change](session, session.get(Assignment, aid), _user(session, "prof"))
    assert _state() != before


def _loosened_page_course(course: str, session: SessionDep, user: SignedIn) -> Course:
    """A page's InstructorCourse dependency loosened by mistake to let every member of the course through."""
    found = session.scalar(select(Course).where(Course.name == course))
    assert found is not None and found.id == user.course_id
    return found


def _loosened_page_assignment(assignment_id: int, session: SessionDep, user: SignedIn) -> Assignment:
    return session.get(Assignment, assignment_id)


def _loosened_api_course(course: MemberCourse) -> Course:
    return course


@pytest.fixture
def loosened(api):
    """The app with the instructor-only dependencies of the set-up pages and the course API replaced by ones that
    let any member of the course through (as one mistaken edit of a route would)."""
    from grader.web import deps
    from grader.main import app
    from grader.pages import auth

    for fn, loose in ((auth.instructor_course, _loosened_page_course),
                      (auth.instructors_assignment, _loosened_page_assignment),
                      (deps.instructor_course, _loosened_api_course)):
        app.dependency_overrides[fn] = loose
    try:
        yield api
    finally:
        for fn in (auth.instructor_course, auth.instructors_assignment, deps.instructor_course):
            app.dependency_overrides.pop(fn, None)


@pytest.mark.parametrize("who", ["tess", "alice"])
@pytest.mark.clock("2026-11-20T12:00:00Z")  # the extension below names January 2027
def test_a_loosened_page_or_api_dependency_still_cannot_let_a_ta_or_student_change_the_course(loosened, who):
    api = loosened
    aid = create(api).json()["id"]
    before = _state()
    zone = page_post(api, "/courses/l03/setup/timezone", {"timezone": "Europe/Berlin"}, who=who)
    assert zone.status_code == 404, zone.text  # a page answers a role refusal with the not-found page
    patched = api.client.patch("/v1/courses/l03", json={"timezone": "Europe/Berlin"}, headers=api.as_(who))
    assert patched.status_code == 403 and "only instructors may change a course's settings" in patched.text
    made = api.client.post("/v1/courses/l03/assignments", headers=api.as_(who), json={
        "title": "T", "part": "checkpoints", "open_at": (utcnow() - timedelta(days=1)).isoformat() + "Z",
        "due_at": (utcnow() + timedelta(days=1)).isoformat() + "Z",
        "hard_close_at": (utcnow() + timedelta(days=2)).isoformat() + "Z"})
    assert made.status_code == 403, made.text
    for path, data in [("/courses/l03/setup/assignments", BERLIN_FORM), (f"/assignments/{aid}/edit", BERLIN_FORM),
                       (f"/assignments/{aid}/release", {}),
                       (f"/assignments/{aid}/extensions", {"student": "bob", "due_at": "2027-01-05T12:00",
                                                           "hard_close_at": "2027-01-06T12:00"})]:
        response = page_post(api, path, data, who=who)
        assert response.status_code in (403, 404), (path, response.status_code, response.text[:300])
    assert _state() == before
    assert api.client.get("/v1/courses/l03", headers=api.as_("prof")).json()["timezone"] == "UTC"
