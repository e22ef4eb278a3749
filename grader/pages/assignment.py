"""The instructor's page of one assignment: its settings (times in the course's zone), and per student the dates
that apply (their extension, with who granted it), every attempt with its lateness, raw score, late penalty and
counted score, and which attempt counts. For the course's instructors; anyone else gets the 404 page."""

from __future__ import annotations

from dataclasses import dataclass, field

from fastapi import APIRouter, HTTPException, Request
from fastapi.responses import HTMLResponse
from sqlalchemy import select

from grader import assignments as logic
from grader.api.deps import MAX_ID, SessionDep
from grader.core.rubrics import current_grade
from grader.models import Assignment, Extension, Submission, User
from grader.pages.auth import PageUser
from grader.pages.routes import TEMPLATES, _not_found, _sign_in_redirect

router = APIRouter(include_in_schema=False)


@dataclass
class AttemptRow:
    submission: Submission
    late: str
    counted: logic.Counted | None  # None until graded
    counts: bool


@dataclass
class StudentRow:
    user: User
    extension: Extension | None
    attempts: list[AttemptRow] = field(default_factory=list)

    @property
    def counting(self) -> AttemptRow | None:
        return next((a for a in self.attempts if a.counts), None)


def students_view(session, assignment: Assignment) -> list[StudentRow]:
    """Every student of the course (and anyone else who submitted), by name, with their attempts in order."""
    counting = {c.submission.student_id: c.submission.id
                for c in logic.counted_grades(session=session, assignment=assignment)}
    extensions = {e.student_id: e for e in session.scalars(
        select(Extension).where(Extension.assignment_id == assignment.id))}
    attempts = logic.attempts_by_student(session=session, assignment=assignment)
    people = {u.id: u for u in session.scalars(select(User).where(User.course_id == assignment.course_id,
                                                                  User.role == "student"))}
    people |= {subs[0].student_id: subs[0].student for subs in attempts.values()}
    rows = []
    for user in sorted(people.values(), key=lambda u: u.name):
        row = StudentRow(user=user, extension=extensions.get(user.id))
        for s in attempts.get(user.id, []):
            grade = current_grade(session, s.id)
            counted = logic.counted_score(assignment, s, grade.total, grade.max_total) if grade else None
            row.attempts.append(AttemptRow(submission=s, late=logic.late_text(s.late_seconds), counted=counted,
                                           counts=counting.get(user.id) == s.id))
        rows.append(row)
    return rows


def _instructors_assignment(session, user, assignment_id: int) -> Assignment | None:
    row = session.get(Assignment, assignment_id) if 0 < assignment_id <= MAX_ID else None
    if row is None or user.course_id != row.course_id or user.role != "instructor":
        return None
    return row


@router.get("/assignments/{assignment_id}", response_class=HTMLResponse)
def assignment_page(request: Request, assignment_id: int, session: SessionDep, user: PageUser):
    if user is None:
        return _sign_in_redirect(request)
    assignment = _instructors_assignment(session, user, assignment_id)
    if assignment is None:
        return _not_found(request, user, f"assignment {assignment_id}")
    items = [(i, logic.visibility_of(assignment, i)) for i in logic.item_ids(assignment.lesson, assignment.items)]
    return TEMPLATES.TemplateResponse(request, "assignment.html", {
        "user": user, "a": assignment, "items": items, "students": students_view(session, assignment)})


@router.get("/assignments/{assignment_id}/grades.csv")
def grades_csv_download(request: Request, assignment_id: int, session: SessionDep, user: PageUser):
    """The counted grades as CSV (the API's export), with the page's sign-in."""
    if user is None:
        return _sign_in_redirect(request)
    from grader.api.routes.assignments import counted_grades_csv

    if _instructors_assignment(session, user, assignment_id) is None:
        return _not_found(request, user, f"grades of assignment {assignment_id}")
    try:
        return counted_grades_csv(assignment_id, session, user)
    except HTTPException:
        return _not_found(request, user, f"grades of assignment {assignment_id}")
