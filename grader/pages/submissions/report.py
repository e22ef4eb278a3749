"""A caller's submissions and one submission's report, with what the report page downloads (results.json, the
charts' series, evidence files). Signing in is grader.pages.identity.sign_in; the exports grader.pages.reports.exports.

Same access rules as the API (a student sees their own submissions, instructors and auditors their course's);
anything a caller may not read is a 404 page that reveals nothing. Every asset is served by this app.
"""

from __future__ import annotations

from fastapi import APIRouter, Request
from fastapi.responses import HTMLResponse, JSONResponse, Response

from grader.web import etag
from grader.web.deps import SessionDep
from grader.core.grades import grade_history
from grader.core.rubrics import stored_version
from grader.core.variants import submission_variant
from grader.core.states import SubmissionState
from grader.core.models import Submission
from grader.pages.auth import SignedIn, SignedInFetch
from grader.pages.errors import not_found
from grader.pages.templates import TEMPLATES, request_locale
from grader.pages.views import report_view
from grader.services.identity import access
from grader.services.setup import assignments
from grader.services.reports import exports, series as chart_series
from grader.services.submissions import submit as submissions
from grader.services.errors import NotFound
from grader.services.submissions.visibility import attempt_standing, grade_view
from grader import i18n
from rubric.lesson import LessonNotFound
from rubric.lesson import lesson as installed_lesson
from rubric.variants import texts

PART_TITLES = {
    "A": "Part A: contact and time step", "B": "Part B: friction and stopping distance",
    "checkpoint": "Concept checkpoints", "hands_on": "Hands-on exercise", "extension": "Extension",
}
router = APIRouter(include_in_schema=False)



def _readable(session, user, submission_id: int) -> Submission | None:
    # Pages answer an id outside the keys' range like any unknown id: the 404 page (the API says 422).
    try:
        return access.readable_submission(session=session, user=user, submission_id=submission_id)
    except NotFound:
        return None


@router.get("/submissions", response_class=HTMLResponse)
def submissions_page(request: Request, session: SessionDep, user: SignedIn):
    rows = submissions.visible_submissions(session=session, user=user)
    grades = {s.id: v for s in rows if (v := grade_view(session=session, submission=s, user=user, report=False)).shown}
    return TEMPLATES.TemplateResponse(request, "submissions/submissions.html", {
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
def report_page(request: Request, submission_id: int, session: SessionDep, user: SignedIn):
    submission = _readable(session, user, submission_id)
    if submission is None:
        return not_found(request, user, f"submission {submission_id}")
    # the report (the largest column) loads only if the page is built: a 304 never reads it
    grade = grade_view(session=session, submission=submission, user=user, report=False)
    attempt = _attempts(session, [submission], user).get(submission.id)

    def build():
        return report_response(request, session, user, submission, grade=grade, attempt=attempt)

    # A complete report answers 304 to a browser that holds it, and is rendered once per validator (grader.web.etag).
    tag = etag.etag_of("report-page", etag.report_state(session, submission, user, grade), request_locale(request),
                       {k: v for k, v in (attempt or {}).items() if k != "assignment"}, str(request.url)) \
        if etag.complete(submission, grade) else None
    return etag.conditional(request, tag, build, cache_key="report-page",
                            until=tag and etag.shown_until(session, submission, user, grade))


def report_response(request: Request, session, user, submission: Submission, *, grade=None, attempt=None,
                    extra: dict | None = None, status_code: int = 200) -> HTMLResponse:
    """The report page as `user` reads it; `extra` is context a form's refusal adds (the override form shown again
    with its error and what was typed, grader.pages.submissions.review_requests)."""
    if grade is None:
        grade = grade_view(session=session, submission=submission, user=user, report=False)
        attempt = _attempts(session, [submission], user).get(submission.id)
    view = report_view(submission, grade if grade.shown else None, grade.withheld_runs)
    return TEMPLATES.TemplateResponse(request, "submissions/report.html", {
        "user": user, "view": view, "part_titles": PART_TITLES, "attempt": attempt, "lesson": submission.lesson,
        "lesson_part_titles": _lesson_part_titles(submission.lesson, request_locale(request)),
        "history": [] if grade.hidden else grade_history(session, submission.id),
        "charts": _charts(submission, grade.withheld_runs),
        "series_url": f"/submissions/{submission.id}/series.json",
        "variant_questions": _variant_questions(session, submission, view, request_locale(request)),
    } | (extra or {}), status_code=status_code)


def _lesson_part_titles(name: str, locale: str) -> dict[str, str]:
    """The headings a lesson declares for its parts, in the reader's language (its texts file's part_titles)."""
    try:
        declared = installed_lesson(name).part_titles
    except LessonNotFound:
        return {}
    return {part: i18n.lesson_word(locale, "part_titles", text, name) for part, text in declared.items()}


def _variant_questions(session, submission: Submission, view, locale: str) -> dict[str, str]:
    """A variant submission's questions in the reader's language, by item id: its report stores them in English with
    the variant's numbers, which the lesson's translations (of the shipped wording) do not know. Only where the stored
    text is the variant's own English question, so the page never words a question otherwise than it was graded."""
    variant = submission_variant(submission)
    if variant is None or view.grade is None or locale == "en":
        return {}
    stored = view.grade.stored
    book = stored_version(session, stored.rubric_lesson, stored.rubric_version, stored.rubric_hash)
    items = {item.id: item for item in book.items} if book is not None else {}
    return {row.id: texts.item_question(items[row.id], variant, locale) for row in view.items
            if row.id in items and texts.item_question(items[row.id], variant) == row.question}


def _charts(submission: Submission, withheld: dict[str, str]) -> list:
    """The report's charts once the submission is graded (as the PNGs were, drawn after grading), without the
    runs whose measurements decide an item withheld from the reader (GradeView.withheld_runs)."""
    if submission.status != SubmissionState.GRADED:
        return []
    return chart_series.report_charts(submission, withheld)


@router.get("/submissions/{submission_id}/results.json")
def results_download(request: Request, submission_id: int, session: SessionDep, user: SignedIn):
    """The stored grade report (every item with prediction, expected, evidence, tolerances and verdict) as JSON;
    for a student, the items their assignment withholds yet are masked."""
    submission = _readable(session, user, submission_id)
    grade = grade_view(session=session, submission=submission, user=user) if submission else None
    if grade is None or not grade.shown:
        return not_found(request, user, f"grade of submission {submission_id}")
    tag = etag.etag_of("results", etag.report_state(session, submission, user, grade)) \
        if etag.complete(submission, grade) else None
    return etag.conditional(request, tag, lambda: JSONResponse(grade.report, headers={
        "Content-Disposition": f'attachment; filename="submission-{submission.id}-results.json"'}),
        cache_key="results", until=tag and etag.shown_until(session, submission, user, grade))


@router.get("/submissions/{submission_id}/series.json")
def series_json(request: Request, submission_id: int, session: SessionDep, user: SignedInFetch):
    """The measured series the report's charts draw, read from the database (any API host serves them): to whoever
    may read the submission, like its evidence downloads; they hold no item's score or verdict."""
    submission = _readable(session, user, submission_id)
    if submission is None:
        return not_found(request, user, f"series of submission {submission_id}")
    # The runs deciding an item withheld from this reader carry no series (GradeView.withheld_runs): what is withheld
    # (the items, why, the lesson's items withheld from the student elsewhere, and the grade they are withheld from) is
    # part of the validator, like the report's.
    grade = grade_view(session=session, submission=submission, user=user, report=False)
    # Built once per state of its runs (and reader) while the submission is finished: a report view asks again.
    # a withheld run's reuse and end time would be guessed from the tag: its re-sends say it changed instead
    withheld = grade.withheld_runs
    tag = etag.etag_of("series", [user.id, submission.id, chart_series.SHAPE, *[
        [r.id, r.status, r.result_status, r.delivery] if r.name in withheld else
        [r.id, r.status, r.result_status, r.reused_from_id, str(r.finished_at)] for r in submission.case_runs]],
        sorted(grade.hidden.items()), sorted(grade.lesson_hidden.items()),
        grade.stored.id if grade.stored is not None else None) \
        if submission.status in (SubmissionState.GRADED, SubmissionState.FAILED) else None
    return etag.conditional(request, tag, lambda: JSONResponse(chart_series.submission_series(
        submission=submission, withheld=grade.withheld_runs), headers={"Cache-Control": "private, no-cache"}),
        cache_key="series")


@router.get("/submissions/{submission_id}/case-runs/{name}/{filename}")
def evidence_file(request: Request, submission_id: int, name: str, filename: str, session: SessionDep,
                  user: SignedIn):
    submission = _readable(session, user, submission_id)
    if submission is None:
        return not_found(request, user, f"file {filename} of case run {name}")
    withheld = grade_view(session=session, submission=submission, user=user, report=False).withheld_runs
    try:
        body, media_type = exports.evidence_file(submission=submission, name=name, filename=filename,
                                                 withheld=withheld)
    except NotFound:
        return not_found(request, user, f"file {filename} of case run {name}")
    return Response(body, media_type=media_type, headers={
        "Content-Disposition": f'attachment; filename="{submission.id}-{name}-{filename}"'})


