"""Grade exports for instructors: the course's grades as CSV, one submission as Gradescope results.json."""

from __future__ import annotations

from fastapi import APIRouter
from fastapi.responses import PlainTextResponse, Response

from grader.web.deps import InstructorCourse, InstructorUser, SessionDep, SubmissionDep
from grader.api.responses import csv_ok, errors
from grader.services.reports import exports

router = APIRouter(tags=["exports"], responses=errors(401, 403, 404, 422))


# response_class=Response: the success is CSV, but FastAPI would document the JSON errors under the response
# class's media type; with no media type of its own they stay application/json.
@router.get("/courses/{course}/grades.csv", response_class=Response,
            responses=csv_ok("One row per graded submission, or per student with latest=true"))
def course_grades_csv(course: InstructorCourse, session: SessionDep, latest: bool = False):
    """The course's current grades as CSV, with each row's submission id and time (UTC): every graded submission in
    submission order, or with `latest=true` each student's latest graded attempt (the one the dashboard counts)."""
    name, text = exports.course_grades_csv(session=session, course=course, latest=latest)
    return PlainTextResponse(text, media_type="text/csv", headers={"Content-Disposition": f'attachment; filename="{name}"'})


@router.get("/submissions/{submission_id}/gradescope.json", responses=errors(409, _409="Not graded yet"))
def gradescope(submission: SubmissionDep, session: SessionDep, user: InstructorUser) -> dict:
    """Gradescope results.json for one graded submission; each item's visibility is its assignment's for that item
    (immediate: visible, after_due: after_due_date, on_release: after_published)."""
    return exports.gradescope(session=session, submission=submission)
