"""The pages people look at, server-rendered from grader/templates: sign-in, a caller's submissions, one report.
(The class dashboard's pages are grader.pages.dashboard.)

Same access rules as the API (a student sees their own submissions, instructors and auditors their course's);
anything a caller may not read is a 404 page that reveals nothing. Every asset is served by this app.
"""

from __future__ import annotations

from fastapi import APIRouter, Form, Request, status
from fastapi.responses import HTMLResponse, JSONResponse, PlainTextResponse, RedirectResponse, Response

from grader.api import etag
from grader.api.deps import SessionDep
from grader.core.rubrics import current_grade, grade_history
from grader.core.states import Role, SubmissionState
from grader.models import Submission
from grader.pages.auth import COOKIE, InstructorCourse, PageUser, clear_session_cookie, set_session_cookie
from grader.pages.errors import not_found, sign_in_redirect
from grader.pages.templates import TEMPLATES, request_locale
from grader.pages.views import report_view
from grader.services import access, accounts, assignments, exports, figure_series, sessions, submissions
from grader.services.errors import NotFound
from grader.services.visibility import attempt_standing, grade_view
from grader.settings import settings

PART_TITLES = {
    "A": "Part A: contact and time step", "B": "Part B: friction and stopping distance",
    "checkpoint": "Concept checkpoints", "hands_on": "Hands-on exercise", "extension": "Extension",
}
router = APIRouter(include_in_schema=False)


_sign_in_redirect = sign_in_redirect
_not_found = not_found


def _readable(session, user, submission_id: int) -> Submission | None:
    # Pages answer an id outside the keys' range like any unknown id: the 404 page (the API says 422).
    try:
        return access.readable_submission(session=session, user=user, submission_id=submission_id)
    except NotFound:
        return None


@router.get("/", response_class=HTMLResponse)
def home(request: Request, user: PageUser):
    if user is None:
        return _sign_in_redirect(request)
    return RedirectResponse("/submissions", status_code=status.HTTP_303_SEE_OTHER)


def _sign_in_page(request: Request, user, next: str, error: str | None = None, code: int = status.HTTP_200_OK):
    return TEMPLATES.TemplateResponse(request, "sign_in.html", {
        "user": user, "next": _safe_next(next), "error": error, "idle_hours": round(settings.session_idle_s / 3600),
        "lifetime_days": round(settings.session_lifetime_s / 86400)}, status_code=code)


@router.get("/sign-in", response_class=HTMLResponse)
def sign_in_form(request: Request, user: PageUser, next: str = "/submissions"):
    return _sign_in_page(request, user, next)


@router.post("/sign-in", response_class=HTMLResponse)
def sign_in(request: Request, session: SessionDep, token: str = Form(""), next: str = Form("/submissions")):
    """Opens a page session for a working token; the cookie gets the session's secret, never the token. Wrong tokens
    are counted per client address, and past settings.rate_limit_sign_in_failures refused (429) before any look-up."""
    address = request.client.host if request.client else "unknown"
    sessions.refuse_failing_address(address)
    row = accounts.find_token(session=session, token=token.strip())
    refusal = accounts.token_refusal(row)
    if refusal is not None:
        sessions.count_failed_sign_in(address)
        error = "That token is unknown or has been revoked." if row is None else f"That {refusal}."
        return _sign_in_page(request, None, next, error, status.HTTP_401_UNAUTHORIZED)
    if request.cookies.get(COOKIE):  # a session this browser held before ends with the new one
        sessions.revoke_session(session=session, secret=request.cookies[COOKIE])
    secret = sessions.open_session(session=session, user=row.user, token=row)
    session.commit()
    response = RedirectResponse(_safe_next(next), status_code=status.HTTP_303_SEE_OTHER)
    set_session_cookie(response, request, secret)
    return response


@router.post("/sign-out")
def sign_out(request: Request, session: SessionDep):
    """Revokes the session: the same cookie, kept or copied, no longer opens a page."""
    if request.cookies.get(COOKIE):
        sessions.revoke_session(session=session, secret=request.cookies[COOKIE])
        session.commit()
    response = RedirectResponse("/sign-in", status_code=status.HTTP_303_SEE_OTHER)
    clear_session_cookie(response)
    return response


def _safe_next(target: str) -> str:
    """Only a path on this site: never an open redirect to another host."""
    return target if target.startswith("/") and not target.startswith("//") else "/submissions"


@router.get("/submissions", response_class=HTMLResponse)
def submissions_page(request: Request, session: SessionDep, user: PageUser):
    if user is None:
        return _sign_in_redirect(request)
    rows = submissions.visible_submissions(session=session, user=user)
    grades = {s.id: v for s in rows if (v := grade_view(session=session, submission=s, user=user, report=False)).shown}
    return TEMPLATES.TemplateResponse(request, "submissions.html", {
        "user": user, "submissions": rows[::-1], "grades": grades, "attempts": _attempts(session, rows, user)})


def _attempts(session, rows: list[Submission], user) -> dict[int, dict]:
    """Per submission to an assignment, what the caller may see of it: attempt, lateness, penalty, whether it
    counts (grader.api.views.submission_public decides what a withheld grade leaves out)."""
    out = {}
    for s in rows:
        if s.assignment is not None:
            out[s.id] = {"assignment": s.assignment, "attempt": s.attempt,
                         "late": assignments.late_text(s.late_seconds)} | attempt_standing(session, s, user)
    return out


@router.get("/submissions/{submission_id}", response_class=HTMLResponse)
def report_page(request: Request, submission_id: int, session: SessionDep, user: PageUser):
    if user is None:
        return _sign_in_redirect(request)
    submission = _readable(session, user, submission_id)
    if submission is None:
        return _not_found(request, user, f"submission {submission_id}")
    # the report (the largest column) loads only if the page is built: a 304 never reads it
    grade = grade_view(session=session, submission=submission, user=user, report=False)
    hidden = bool(grade.hidden)
    attempt = _attempts(session, [submission], user).get(submission.id)

    def build():
        view = report_view(submission, grade if grade.shown else None, grade.withheld_runs)
        return TEMPLATES.TemplateResponse(request, "report.html", {
            "user": user, "view": view, "part_titles": PART_TITLES, "attempt": attempt,
            "history": [] if hidden else grade_history(session, submission.id),
            "charts": _charts(submission, grade.withheld_runs),
            "series_url": f"/submissions/{submission.id}/series.json"})

    # A complete report answers 304 to a browser that holds it, and is rendered once per validator (grader.api.etag).
    tag = etag.etag_of("report-page", etag.report_state(session, submission, user, grade), request_locale(request),
                       {k: v for k, v in (attempt or {}).items() if k != "assignment"}, str(request.url)) \
        if etag.complete(submission, grade) else None
    return etag.conditional(request, tag, build, cache_key="report-page")


def _charts(submission: Submission, withheld: dict[str, str]) -> list:
    """The report's charts once the submission is graded (as the PNG figures were, drawn after grading), without the
    runs whose measurements decide an item withheld from the reader (GradeView.withheld_runs)."""
    if submission.status != SubmissionState.GRADED:
        return []
    return figure_series.report_charts(submission, withheld)


@router.get("/submissions/{submission_id}/results.json")
def results_download(request: Request, submission_id: int, session: SessionDep, user: PageUser):
    """The stored grade report (every item with prediction, expected, evidence, tolerances and verdict) as JSON;
    for a student, the items their assignment withholds yet are masked."""
    if user is None:
        return _sign_in_redirect(request)
    submission = _readable(session, user, submission_id)
    grade = grade_view(session=session, submission=submission, user=user) if submission else None
    if grade is None or not grade.shown:
        return _not_found(request, user, f"grade of submission {submission_id}")
    tag = etag.etag_of("results", etag.report_state(session, submission, user, grade)) \
        if etag.complete(submission, grade) else None
    return etag.conditional(request, tag, lambda: JSONResponse(grade.report, headers={
        "Content-Disposition": f'attachment; filename="submission-{submission.id}-results.json"'}),
        cache_key="results")


@router.get("/submissions/{submission_id}/series.json")
def figure_series_json(request: Request, submission_id: int, session: SessionDep, user: PageUser):
    """The measured series the report's charts draw, read from the database (any API host serves them): to whoever
    may read the submission, like its evidence downloads; they hold no item's score or verdict."""
    if user is None:
        return Response(status_code=status.HTTP_401_UNAUTHORIZED)
    submission = _readable(session, user, submission_id)
    if submission is None:
        return _not_found(request, user, f"figures of submission {submission_id}")
    # The runs deciding an item withheld from this reader carry no series (GradeView.withheld_runs): what is withheld
    # (the items, why, and the grade they are withheld from) is part of the validator, like the report's.
    grade = grade_view(session=session, submission=submission, user=user, report=False)
    # Built once per state of its runs (and reader) while the submission is finished: a report view asks again.
    tag = etag.etag_of("series", [user.id, submission.id, figure_series.SHAPE, *[
        [r.id, r.status, r.result_status, r.reused_from_id, str(r.finished_at)] for r in submission.case_runs]],
        sorted(grade.hidden.items()), grade.stored.id if grade.stored is not None else None) \
        if submission.status in (SubmissionState.GRADED, SubmissionState.FAILED) else None
    return etag.conditional(request, tag, lambda: JSONResponse(figure_series.submission_series(
        submission=submission, withheld=grade.withheld_runs), headers={"Cache-Control": "private, no-cache"}),
        cache_key="series")


@router.get("/submissions/{submission_id}/case-runs/{name}/{filename}")
def evidence_file(request: Request, submission_id: int, name: str, filename: str, session: SessionDep,
                  user: PageUser):
    if user is None:
        return _sign_in_redirect(request)
    submission = _readable(session, user, submission_id)
    if submission is None:
        return _not_found(request, user, f"file {filename} of case run {name}")
    withheld = grade_view(session=session, submission=submission, user=user, report=False).withheld_runs
    try:
        body, media_type = exports.evidence_file(submission=submission, name=name, filename=filename,
                                                 withheld=withheld)
    except NotFound:
        return _not_found(request, user, f"file {filename} of case run {name}")
    return Response(body, media_type=media_type, headers={
        "Content-Disposition": f'attachment; filename="{submission.id}-{name}-{filename}"'})


@router.get("/courses/{course}/grades.csv")
def grades_csv_download(course: InstructorCourse, session: SessionDep, latest: bool = False):
    """The course's grades as CSV (instructors; the API's export, with the page's sign-in)."""
    name, text = exports.course_grades_csv(session=session, course=course, latest=latest)
    return PlainTextResponse(text, media_type="text/csv", headers={"Content-Disposition": f'attachment; filename="{name}"'})


@router.get("/submissions/{submission_id}/gradescope.json")
def gradescope_download(request: Request, submission_id: int, session: SessionDep, user: PageUser):
    """Gradescope results.json of one graded submission, for its course's instructors."""
    if user is None:
        return _sign_in_redirect(request)
    submission = _readable(session, user, submission_id)
    if submission is None or user.role != Role.INSTRUCTOR or current_grade(session, submission.id, report=False) is None:
        return _not_found(request, user, f"Gradescope results of submission {submission_id}")
    return JSONResponse(exports.gradescope(session=session, submission=submission), headers={
        "Content-Disposition": f'attachment; filename="submission-{submission.id}-gradescope-results.json"'})
