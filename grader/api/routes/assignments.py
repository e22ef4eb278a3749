"""Assignments of a course: create and list (instructors), read one, grant a student an extension."""

from __future__ import annotations

import csv
import io

from fastapi import APIRouter, HTTPException, status
from fastapi.responses import PlainTextResponse, Response
from sqlalchemy import select

from grader import assignments as logic
from grader.api.deps import CurrentUser, Name, RowId, SessionDep
from grader.api.errors import FieldError
from grader.api.responses import csv_ok, errors
from grader.models import Assignment, Course, Extension, User, utcnow
from grader.schemas import (AssignmentCreate, AssignmentPublic, CountedGradePublic, ExtensionCreate,
                            ExtensionPublic)

router = APIRouter(tags=["assignments"], responses=errors(401, 404, 422))


def assignment_public(a: Assignment) -> AssignmentPublic:
    return AssignmentPublic(
        id=a.id, course=a.course.name, title=a.title, lesson=a.lesson, items=a.items,
        item_ids=logic.item_ids(a.lesson, a.items), open_at=a.open_at, due_at=a.due_at, hard_close_at=a.hard_close_at,
        late_penalty_per_day=a.late_penalty_per_day, late_penalty_cap=a.late_penalty_cap,
        max_attempts=a.max_attempts, max_per_hour=a.max_per_hour, counted_attempt=a.counted_attempt,
        visibility=a.visibility, item_visibility=a.item_visibility or {}, released_at=a.released_at,
        created_by=a.created_by.name, created_at=a.created_at)


def own_course(course: str, session, user: User) -> Course:
    """The caller's own course; any other course is 404, whether or not it exists."""
    row = session.scalar(select(Course).where(Course.name == course))
    if row is None or row.id != user.course_id:
        raise HTTPException(status.HTTP_404_NOT_FOUND, f"course {course!r} not found")
    return row


def instructor(user: User) -> None:
    if user.role != "instructor":
        raise HTTPException(status.HTTP_403_FORBIDDEN, "only instructors manage assignments")


def readable_assignment(assignment_id: int, session, user: User) -> Assignment:
    row = session.get(Assignment, assignment_id)
    if row is None or row.course_id != user.course_id:
        raise HTTPException(status.HTTP_404_NOT_FOUND, f"assignment {assignment_id} not found")
    return row


@router.post("/courses/{course}/assignments", status_code=status.HTTP_201_CREATED, response_model=AssignmentPublic,
             responses=errors(403, 413))
def create_assignment(course: Name, body: AssignmentCreate, session: SessionDep, user: CurrentUser):
    """Create an assignment in the instructor's own course."""
    row = own_course(course, session, user)
    instructor(user)
    held = logic.item_ids(body.lesson, body.items)
    strangers = [{"field": f"item_visibility.{item}",
                  "rule": f"not an item of this assignment ({body.items}: {', '.join(held)})"}
                 for item in body.item_visibility if item not in held]
    if strangers:
        raise FieldError(422, "invalid assignment", strangers)
    assignment = Assignment(course_id=row.id, created_by_id=user.id, **body.model_dump())
    session.add(assignment)
    session.commit()
    return assignment_public(assignment)


@router.get("/courses/{course}/assignments", response_model=list[AssignmentPublic])
def list_assignments(course: Name, session: SessionDep, user: CurrentUser):
    """The course's assignments, by due date (anyone in the course)."""
    row = own_course(course, session, user)
    rows = session.scalars(select(Assignment).where(Assignment.course_id == row.id)
                           .order_by(Assignment.due_at, Assignment.id)).all()
    return [assignment_public(a) for a in rows]


@router.get("/assignments/{assignment_id}", response_model=AssignmentPublic)
def get_assignment(assignment_id: RowId, session: SessionDep, user: CurrentUser):
    """One assignment of the caller's course."""
    return assignment_public(readable_assignment(assignment_id, session, user))


@router.post("/assignments/{assignment_id}/release", response_model=AssignmentPublic, responses=errors(403))
def release(assignment_id: RowId, session: SessionDep, user: CurrentUser):
    """Show the assignment's scores and feedback to its students (visibility on_release; an instructor of the
    course). Releasing again keeps the first release time."""
    assignment = readable_assignment(assignment_id, session, user)
    instructor(user)
    if assignment.released_at is None:
        assignment.released_at = utcnow()
        session.commit()
    return assignment_public(assignment)


@router.post("/assignments/{assignment_id}/extensions", status_code=status.HTTP_201_CREATED,
             response_model=ExtensionPublic, responses=errors(403, 413))
def grant_extension(assignment_id: RowId, body: ExtensionCreate, session: SessionDep, user: CurrentUser):
    """Give one student their own due date and hard close (an instructor of the course; replaces an earlier one)."""
    assignment = readable_assignment(assignment_id, session, user)
    instructor(user)
    student = session.scalar(select(User).where(User.course_id == assignment.course_id, User.name == body.student,
                                                User.role == "student"))
    if student is None:
        raise FieldError(422, "unknown student", [{"field": "student",
                                                   "rule": f"no student {body.student!r} in this course"}])
    ext = session.scalar(select(Extension).where(Extension.assignment_id == assignment.id,
                                                 Extension.student_id == student.id))
    if ext is None:
        ext = Extension(assignment_id=assignment.id, student_id=student.id)
        session.add(ext)
    ext.due_at, ext.hard_close_at, ext.granted_by_id = body.due_at, body.hard_close_at, user.id
    ext.granted_at = utcnow()
    session.commit()
    return ExtensionPublic(assignment_id=assignment.id, student=student.name, due_at=ext.due_at,
                           hard_close_at=ext.hard_close_at, granted_by=user.name, granted_at=ext.granted_at)


def _counted(assignment_id: int, session, user: User) -> tuple[Assignment, list[CountedGradePublic]]:
    assignment = readable_assignment(assignment_id, session, user)
    instructor(user)
    rows = [logic.counted_public(c) for c in logic.counted_grades(session=session, assignment=assignment)]
    return assignment, rows


@router.get("/assignments/{assignment_id}/grades", response_model=list[CountedGradePublic], responses=errors(403))
def counted_grades(assignment_id: RowId, session: SessionDep, user: CurrentUser):
    """Per student, the attempt that counts (latest or best, as the assignment says): raw score, late penalty and
    counted score (instructors)."""
    return _counted(assignment_id, session, user)[1]


COLUMNS = ("student", "counted_score", "raw_score", "max_score", "penalty", "late_seconds", "attempt",
           "submission_id", "submitted_at_utc")


# response_class=Response: the success is CSV while the errors stay JSON (as grader.api.routes.exports does).
@router.get("/assignments/{assignment_id}/grades.csv", response_class=Response, responses={
    **csv_ok("One row per student: the counted attempt, its raw score, the late penalty and the counted score"),
    **errors(403)})
def counted_grades_csv(assignment_id: RowId, session: SessionDep, user: CurrentUser):
    """The assignment's counted grades as CSV (instructors): student, counted score, raw score, penalty, attempt,
    submission and when it was submitted (UTC)."""
    assignment, rows = _counted(assignment_id, session, user)
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow(COLUMNS)
    for r in rows:
        writer.writerow([r.student, f"{r.counted_score:g}", f"{r.raw_score:g}", f"{r.max_score:g}", f"{r.penalty:g}",
                         r.late_seconds, r.attempt, r.submission_id, r.submitted_at.isoformat()])
    name = f"{assignment.course.name}-assignment-{assignment.id}-grades.csv"
    return PlainTextResponse(out.getvalue(), media_type="text/csv",
                             headers={"Content-Disposition": f'attachment; filename="{name}"'})
