"""Grade exports for instructors: the course's grades as CSV, one submission as Gradescope results.json."""

from __future__ import annotations

from fastapi import APIRouter, HTTPException, status
from fastapi.responses import PlainTextResponse, Response
from sqlalchemy import select

from grader.api.deps import CurrentUser, Name, SessionDep, SubmissionDep
from grader.api.responses import csv_ok, errors
from grader.core.rubrics import current_grade
from grader.models import Course, Grade, Submission

router = APIRouter(tags=["exports"], responses=errors(401, 403, 404, 422))


def _report(grade: Grade):
    from rubric.scoring import GradeReport

    return GradeReport.model_validate(grade.report)


def _instructor(user) -> None:
    if user.role != "instructor":
        raise HTTPException(status.HTTP_403_FORBIDDEN, "exports are for instructors")


# response_class=Response: the success is CSV, but FastAPI would document the JSON errors under the response
# class's media type; with no media type of its own they stay application/json.
@router.get("/courses/{course}/grades.csv", response_class=Response,
            responses=csv_ok("One row per graded submission, or per student with latest=true"))
def course_grades_csv(course: Name, session: SessionDep, user: CurrentUser, latest: bool = False):
    """The course's current grades as CSV, with each row's submission id and time (UTC): every graded submission in
    submission order, or with `latest=true` each student's latest graded attempt (the one the dashboard counts)."""
    _instructor(user)
    row = session.scalar(select(Course).where(Course.name == course))
    if row is None or row.id != user.course_id:
        raise HTTPException(status.HTTP_404_NOT_FOUND, f"course {course!r} not found")
    from rubric.exports import grades_csv

    graded = session.execute(select(Submission, Grade).join(Grade, Grade.submission_id == Submission.id)
                             .where(Submission.course_id == row.id, Grade.superseded_at.is_(None))
                             .order_by(Submission.id)).all()
    if latest:
        graded = sorted({s.student_id: (s, g) for s, g in graded}.values(), key=lambda sg: sg[0].student.name)
    text = grades_csv([(s.student.name, _report(g)) for s, g in graded],
                      submissions=[(s.id, f"{s.created_at.isoformat()}+00:00") for s, _ in graded])
    name = f"{row.name}-{'latest' if latest else 'all'}-grades.csv"
    return PlainTextResponse(text, media_type="text/csv", headers={"Content-Disposition": f'attachment; filename="{name}"'})


@router.get("/submissions/{submission_id}/gradescope.json", responses=errors(409, _409="Not graded yet"))
def gradescope(submission: SubmissionDep, session: SessionDep, user: CurrentUser) -> dict:
    """Gradescope results.json for one graded submission; each item's visibility is its assignment's for that item
    (immediate: visible, after_due: after_due_date, on_release: after_published)."""
    _instructor(user)
    grade = current_grade(session, submission.id)
    if grade is None:
        raise HTTPException(status.HTTP_409_CONFLICT, f"submission {submission.id} is {submission.status}, not graded")
    from rubric.exports import gradescope_results

    from grader.assignments import GRADESCOPE_VISIBILITY, visibility_of

    report = _report(grade)
    shown = ({i.id: GRADESCOPE_VISIBILITY[visibility_of(submission.assignment, i.id)] for i in report.items}
             if submission.assignment is not None else {})
    return gradescope_results(report, grade.execution_s, shown)
