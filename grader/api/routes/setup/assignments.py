"""Assignments of a course: create and list (instructors), read one, grant a student an extension and list them."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Depends, status
from fastapi.responses import PlainTextResponse, Response

from grader.web.deps import CurrentUser, InstructorCourse, InstructorUser, MemberCourse, RowId, SessionDep, StaffUser
from grader.services.setup import assignments as logic
from grader.services.reports import exports
from grader.api.responses import csv_ok, errors
from grader.core.models import Assignment
from grader.core.schemas import (AssignmentCreate, AssignmentPublic, CountedGradePublic, ExtensionCreate,
                            ExtensionPublic)

router = APIRouter(tags=["assignments"], responses=errors(401, 404, 422))


def assignment_public(a: Assignment) -> AssignmentPublic:
    return AssignmentPublic(
        id=a.id, course=a.course.name, title=a.title, lesson=a.lesson, part=a.part,
        item_ids=logic.item_ids(a.lesson, a.part), open_at=a.open_at, due_at=a.due_at, hard_close_at=a.hard_close_at,
        late_penalty_per_day=a.late_penalty_per_day, late_penalty_cap=a.late_penalty_cap,
        max_attempts=a.max_attempts, max_per_hour=a.max_per_hour, counted_attempt=a.counted_attempt,
        visibility=a.visibility, item_visibility=a.item_visibility or {}, released_at=a.released_at,
        created_by=a.created_by.name, created_at=a.created_at)


def readable_assignment(assignment_id: RowId, session: SessionDep, user: CurrentUser) -> Assignment:
    """An assignment of the caller's course; 404 for any other."""
    return logic.assignment_of(session=session, user=user, assignment_id=assignment_id)


ReadableAssignment = Annotated[Assignment, Depends(readable_assignment)]


def instructors_assignment(assignment: ReadableAssignment, user: InstructorUser) -> Assignment:
    return assignment


InstructorsAssignment = Annotated[Assignment, Depends(instructors_assignment)]


@router.post("/courses/{course}/assignments", status_code=status.HTTP_201_CREATED, response_model=AssignmentPublic,
             responses=errors(403, 413))
def create_assignment(course: InstructorCourse, body: AssignmentCreate, session: SessionDep, user: CurrentUser):
    """Create an assignment in the instructor's own course."""
    return assignment_public(logic.create(session=session, course=course, user=user, fields=body.model_dump()))


@router.get("/courses/{course}/assignments", response_model=list[AssignmentPublic])
def list_assignments(course: MemberCourse, session: SessionDep):
    """The course's assignments, by due date (anyone in the course)."""
    return [assignment_public(a) for a in logic.of_course(session=session, course=course)]


@router.get("/assignments/{assignment_id}", response_model=AssignmentPublic)
def get_assignment(assignment: ReadableAssignment):
    """One assignment of the caller's course."""
    return assignment_public(assignment)


@router.post("/assignments/{assignment_id}/release", response_model=AssignmentPublic, responses=errors(403))
def release(assignment: InstructorsAssignment, session: SessionDep, user: CurrentUser):
    """Show the assignment's scores and feedback to its students (visibility on_release; an instructor of the
    course). Releasing again keeps the first release time."""
    return assignment_public(logic.release(session=session, assignment=assignment, by=user))


@router.post("/assignments/{assignment_id}/extensions", status_code=status.HTTP_201_CREATED,
             response_model=ExtensionPublic, responses=errors(403, 413))
def grant_extension(assignment: InstructorsAssignment, body: ExtensionCreate, session: SessionDep,
                    user: CurrentUser):
    """Give one student their own due date and hard close (an instructor of the course; replaces an earlier one)."""
    ext = logic.grant_extension(session=session, assignment=assignment, student_name=body.student, due_at=body.due_at,
                                hard_close_at=body.hard_close_at, user=user)
    return ExtensionPublic(assignment_id=assignment.id, student=ext.student.name, due_at=ext.due_at,
                           hard_close_at=ext.hard_close_at, granted_by=user.name, granted_at=ext.granted_at)


def extension_public(ext) -> ExtensionPublic:
    return ExtensionPublic(assignment_id=ext.assignment_id, student=ext.student.name, due_at=ext.due_at,
                           hard_close_at=ext.hard_close_at, granted_by=ext.granted_by.name, granted_at=ext.granted_at)


@router.get("/assignments/{assignment_id}/extensions", response_model=list[ExtensionPublic], responses=errors(403))
def list_extensions(assignment: ReadableAssignment, user: StaffUser, session: SessionDep):
    """The assignment's extensions, by student: each student's own due date and hard close, who granted them and when
    (instructors and auditors of the course)."""
    return [extension_public(e) for e in logic.extensions(session=session, assignment=assignment)]


@router.get("/assignments/{assignment_id}/grades", response_model=list[CountedGradePublic], responses=errors(403))
def counted_grades(assignment: InstructorsAssignment, session: SessionDep):
    """Per student, the attempt that counts (latest or best, as the assignment says): raw score, late penalty and
    counted score (instructors)."""
    return [logic.counted_public(c) for c in logic.counted_grades(session=session, assignment=assignment)]


# response_class=Response: the success is CSV while the errors stay JSON (as grader.api.routes.reports.exports does).
@router.get("/assignments/{assignment_id}/grades.csv", response_class=Response, responses={
    **csv_ok("One row per student: the counted attempt, its raw score, the late penalty and the counted score"),
    **errors(403)})
def counted_grades_csv(assignment: InstructorsAssignment, session: SessionDep):
    """The assignment's counted grades as CSV (instructors): student, counted score, raw score, penalty, attempt,
    submission and when it was submitted (UTC)."""
    name, text = exports.counted_grades_csv(session=session, assignment=assignment)
    return PlainTextResponse(text, media_type="text/csv", headers={"Content-Disposition": f'attachment; filename="{name}"'})
