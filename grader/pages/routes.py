"""The pages people look at, server-rendered from grader/templates: sign-in, a caller's submissions, one report.
(The class dashboard's pages are grader.pages.dashboard.)

Same access rules as the API (a student sees their own submissions, instructors and auditors their course's);
anything a caller may not read is a 404 page that reveals nothing. Every asset is served by this app.
"""

from __future__ import annotations

from pathlib import Path
from urllib.parse import quote

from fastapi import APIRouter, Form, Request, status
from fastapi.responses import FileResponse, HTMLResponse, RedirectResponse, Response
from fastapi.templating import Jinja2Templates

from grader import crud
from grader.api.deps import MAX_ID, SessionDep
from grader.api.routes.files import EVIDENCE
from grader.core.rubrics import current_grade, grade_history
from grader.assignments import shown_report, withheld_items
from grader.models import Grade, Submission, utcnow
from grader.pages.auth import PageUser, clear_session_cookie, set_session_cookie
from grader.pages.views import report_view
from grader.settings import settings

TEMPLATES = Jinja2Templates(directory=str(Path(__file__).resolve().parent.parent / "templates"))


def local_time(at, user, seconds: bool = False) -> str:
    """A stored time as the signed-in user's course shows it: in the course's time zone, named."""
    from grader.timezones import local

    return local(at, user.course.timezone if user else "UTC", seconds=seconds)


TEMPLATES.env.filters["local"] = local_time
PART_TITLES = {
    "A": "Part A: contact and time step", "B": "Part B: friction and stopping distance",
    "checkpoint": "Concept checkpoints", "hands_on": "Hands-on exercise", "extension": "Extension",
}
router = APIRouter(include_in_schema=False)


def _sign_in_redirect(request: Request) -> RedirectResponse:
    target = request.url.path + (f"?{request.url.query}" if request.url.query else "")
    return RedirectResponse(f"/sign-in?next={quote(target)}", status_code=status.HTTP_303_SEE_OTHER)


def _not_found(request: Request, user, what: str) -> HTMLResponse:
    return TEMPLATES.TemplateResponse(request, "not_found.html", {"user": user, "what": what},
                                      status_code=status.HTTP_404_NOT_FOUND)


def _readable(session, user, submission_id: int) -> Submission | None:
    # Pages answer an id outside the keys' range like any unknown id: the 404 page (the API says 422).
    submission = session.get(Submission, submission_id) if 0 < submission_id <= MAX_ID else None
    if submission is None or not crud.can_read(user=user, submission=submission):
        return None
    return submission


@router.get("/", response_class=HTMLResponse)
def home(request: Request, user: PageUser):
    if user is None:
        return _sign_in_redirect(request)
    return RedirectResponse("/submissions", status_code=status.HTTP_303_SEE_OTHER)


@router.get("/sign-in", response_class=HTMLResponse)
def sign_in_form(request: Request, user: PageUser, next: str = "/submissions"):
    return TEMPLATES.TemplateResponse(request, "sign_in.html", {"user": user, "next": _safe_next(next), "error": None})


@router.post("/sign-in", response_class=HTMLResponse)
def sign_in(request: Request, session: SessionDep, token: str = Form(""), next: str = Form("/submissions")):
    user = crud.user_by_token(session=session, token=token.strip()) if token.strip() else None
    if user is None:
        return TEMPLATES.TemplateResponse(
            request, "sign_in.html",
            {"user": None, "next": _safe_next(next), "error": "That token is unknown or has been revoked."},
            status_code=status.HTTP_401_UNAUTHORIZED)
    response = RedirectResponse(_safe_next(next), status_code=status.HTTP_303_SEE_OTHER)
    set_session_cookie(response, token.strip())
    return response


@router.post("/sign-out")
def sign_out():
    response = RedirectResponse("/sign-in", status_code=status.HTTP_303_SEE_OTHER)
    clear_session_cookie(response)
    return response


def _safe_next(target: str) -> str:
    """Only a path on this site: never an open redirect to another host."""
    return target if target.startswith("/") and not target.startswith("//") else "/submissions"


def shown_grade(session, submission: Submission, user) -> tuple[Grade | None, bool]:
    """The current grade as `user` may see it now, and whether any of it is withheld. A grade with some items
    withheld is a copy (never stored) whose report masks them (grader.assignments.shown_report); with every item
    withheld there is none to show."""
    grade = current_grade(session, submission.id)
    hidden = withheld_items(session=session, submission=submission, user=user, now=utcnow())
    if grade is None or not hidden:
        return grade, bool(hidden)
    report = shown_report(grade.report, hidden)
    if all(item["id"] in hidden for item in report.get("items", [])):
        return None, True
    return Grade(submission_id=grade.submission_id, rubric_lesson=grade.rubric_lesson,
                 rubric_version=grade.rubric_version, rubric_hash=grade.rubric_hash, total=report["total"],
                 max_total=report["max_total"], report=report, execution_s=grade.execution_s,
                 created_at=grade.created_at, completed_at=grade.completed_at), True


@router.get("/submissions", response_class=HTMLResponse)
def submissions_page(request: Request, session: SessionDep, user: PageUser):
    if user is None:
        return _sign_in_redirect(request)
    rows = crud.visible_submissions(session=session, user=user)
    grades = {s.id: g for s in rows if (g := shown_grade(session, s, user)[0]) is not None}
    return TEMPLATES.TemplateResponse(request, "submissions.html", {
        "user": user, "submissions": rows[::-1], "grades": grades, "attempts": _attempts(session, rows, user)})


def _attempts(session, rows: list[Submission], user) -> dict[int, dict]:
    """Per submission to an assignment, what the caller may see of it: attempt, lateness, penalty, whether it
    counts (grader.api.views.submission_public decides what a withheld grade leaves out)."""
    from grader.api.views import submission_public
    from grader.assignments import late_text

    out = {}
    for s in rows:
        if s.assignment is not None:
            public = submission_public(s, session, user)
            out[s.id] = {"assignment": s.assignment, "attempt": s.attempt, "late": late_text(s.late_seconds),
                         "penalty": public.penalty, "counted_score": public.counted_score, "counts": public.counts}
    return out


@router.get("/submissions/{submission_id}", response_class=HTMLResponse)
def report_page(request: Request, submission_id: int, session: SessionDep, user: PageUser):
    if user is None:
        return _sign_in_redirect(request)
    submission = _readable(session, user, submission_id)
    if submission is None:
        return _not_found(request, user, f"submission {submission_id}")
    grade, hidden = shown_grade(session, submission, user)
    view = report_view(submission, grade)
    return TEMPLATES.TemplateResponse(request, "report.html", {
        "user": user, "view": view, "part_titles": PART_TITLES,
        "attempt": _attempts(session, [submission], user).get(submission.id),
        "history": [] if hidden else grade_history(session, submission.id)})


@router.get("/submissions/{submission_id}/results.json")
def results_download(request: Request, submission_id: int, session: SessionDep, user: PageUser):
    """The stored grade report (every item with prediction, expected, evidence, tolerances and verdict) as JSON;
    for a student, the items their assignment withholds yet are masked."""
    if user is None:
        return _sign_in_redirect(request)
    submission = _readable(session, user, submission_id)
    grade = shown_grade(session, submission, user)[0] if submission else None
    if grade is None:
        return _not_found(request, user, f"grade of submission {submission_id}")
    from fastapi.responses import JSONResponse

    return JSONResponse(grade.report, headers={
        "Content-Disposition": f'attachment; filename="submission-{submission.id}-results.json"'})


@router.get("/submissions/{submission_id}/figures/{filename}")
def figure_file(request: Request, submission_id: int, filename: str, session: SessionDep, user: PageUser):
    if user is None:
        return Response(status_code=status.HTTP_401_UNAUTHORIZED)
    submission = _readable(session, user, submission_id)
    path = settings.figures_dir(submission.id) / filename if submission is not None else None
    if path is None or "/" in filename or not filename.endswith(".png") or not path.is_file():
        return _not_found(request, user, f"figure {filename}")
    return FileResponse(path, media_type="image/png")


@router.get("/submissions/{submission_id}/case-runs/{name}/{filename}")
def evidence_file(request: Request, submission_id: int, name: str, filename: str, session: SessionDep,
                  user: PageUser):
    if user is None:
        return _sign_in_redirect(request)
    submission = _readable(session, user, submission_id)
    run = next((r for r in submission.case_runs if r.name == name), None) if submission is not None else None
    path = Path(run.artifact_dir) / filename if run is not None and run.artifact_dir else None
    if path is None or filename not in EVIDENCE or not path.is_file():
        return _not_found(request, user, f"file {filename} of case run {name}")
    return FileResponse(path, media_type=EVIDENCE[filename], filename=f"{submission.id}-{name}-{filename}")


@router.get("/courses/{course}/grades.csv")
def grades_csv_download(request: Request, course: str, session: SessionDep, user: PageUser, latest: bool = False):
    if user is None:
        return _sign_in_redirect(request)
    from fastapi import HTTPException

    from grader.api.routes.exports import course_grades_csv

    try:
        return course_grades_csv(course, session, user, latest=latest)
    except HTTPException:
        return _not_found(request, user, f"grades for course {course}")


@router.get("/submissions/{submission_id}/gradescope.json")
def gradescope_download(request: Request, submission_id: int, session: SessionDep, user: PageUser):
    """Gradescope results.json of one graded submission, for its course's instructors."""
    if user is None:
        return _sign_in_redirect(request)
    from fastapi.responses import JSONResponse

    from grader.api.routes.exports import gradescope

    submission = _readable(session, user, submission_id)
    if submission is None or user.role != "instructor" or current_grade(session, submission.id) is None:
        return _not_found(request, user, f"Gradescope results of submission {submission_id}")
    return JSONResponse(gradescope(submission, session, user), headers={
        "Content-Disposition": f'attachment; filename="submission-{submission.id}-gradescope-results.json"'})
