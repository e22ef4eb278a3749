"""The instructors' downloads from the pages: a course's grades as CSV and one submission's Gradescope results, with
the page's sign-in (the API's exports are grader.api.routes.reports.exports)."""

from __future__ import annotations

from fastapi import APIRouter, Request
from fastapi.responses import JSONResponse, PlainTextResponse

from grader.core.grades import current_grade
from grader.pages.auth import InstructorCourse, SignedIn
from grader.pages.errors import not_found
from grader.services.errors import NotFound
from grader.services.identity import access
from grader.services.reports import exports
from grader.web.deps import SessionDep

router = APIRouter(include_in_schema=False)


@router.get("/courses/{course}/grades.csv")
def grades_csv_download(course: InstructorCourse, session: SessionDep, latest: bool = False):
    """The course's grades as CSV (instructors; the API's export, with the page's sign-in)."""
    name, text = exports.course_grades_csv(session=session, course=course, latest=latest)
    return PlainTextResponse(text, media_type="text/csv", headers={"Content-Disposition": f'attachment; filename="{name}"'})


@router.get("/submissions/{submission_id}/gradescope.json")
def gradescope_download(request: Request, submission_id: int, session: SessionDep, user: SignedIn):
    """Gradescope results.json of one graded submission, for its course's instructors."""
    try:
        submission = access.readable_submission(session=session, user=user, submission_id=submission_id)
    except NotFound:
        submission = None
    if submission is None or not access.is_instructor(user) or current_grade(session, submission.id, report=False) is None:
        return not_found(request, user, f"Gradescope results of submission {submission_id}")
    return JSONResponse(exports.gradescope(session=session, submission=submission), headers={
        "Content-Disposition": f'attachment; filename="submission-{submission.id}-gradescope-results.json"'})
