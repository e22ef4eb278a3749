"""The instructor's page of one assignment: its settings (times in the course's zone), and per student the dates
that apply (their extension, with who granted it), every attempt with its lateness, raw score, late penalty and
counted score, and which attempt counts. For the course's instructors; anyone else gets the 404 page."""

from __future__ import annotations

from dataclasses import dataclass, field

from fastapi import APIRouter, Request
from fastapi.responses import HTMLResponse, PlainTextResponse
from sqlalchemy import select

from grader.api.deps import SessionDep
from grader.core.rubrics import current_grade
from grader.models import Assignment, Extension, Submission, User
from grader.pages.auth import InstructorsAssignment, SignedIn
from grader.pages.templates import TEMPLATES
from grader.services import assignments as logic
from grader.services import exports
from grader.services.visibility import visibility_of

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


@router.get("/assignments/{assignment_id}", response_class=HTMLResponse)
def assignment_page(request: Request, assignment: InstructorsAssignment, session: SessionDep, user: SignedIn):
    items = [(i, visibility_of(assignment, i)) for i in logic.item_ids(assignment.lesson, assignment.part)]
    return TEMPLATES.TemplateResponse(request, "assignment.html", {
        "user": user, "a": assignment, "items": items, "students": students_view(session, assignment)})


@router.get("/assignments/{assignment_id}/grades.csv")
def grades_csv_download(assignment: InstructorsAssignment, session: SessionDep):
    """The counted grades as CSV (the API's export), with the page's sign-in."""
    name, text = exports.counted_grades_csv(session=session, assignment=assignment)
    return PlainTextResponse(text, media_type="text/csv", headers={"Content-Disposition": f'attachment; filename="{name}"'})
