"""The instructor's course set-up pages: the course's time zone, its assignments (create and edit with every setting
the command line has), the roster upload with the new students' tokens and sign-in links shown once, the LMS
platforms registered for it, and the record of every change with who made it and when.

Instructors of the course only; anyone else (auditors too, like the assignment page) gets the 404 page. Every rule
is a service's (grader.services.setup.courses, assignments, roster, sign_in_links); a refused form comes back with what
was typed and each error beside its field. Times are typed and shown in the course's zone.
"""

from __future__ import annotations

import re
from datetime import UTC, datetime
from typing import Annotated
from zoneinfo import available_timezones

from fastapi import APIRouter, Depends, File, Form, Request, UploadFile, status
from fastapi.responses import HTMLResponse, RedirectResponse
from starlette.datastructures import FormData

from grader.web.deps import SessionDep
from grader.core.states import AssignmentParts, Visibility, values
from grader.core.timezones import is_zone, zone
from grader.core.models import Assignment, Course, utcnow
from grader.pages.auth import InstructorCourse, InstructorsAssignment, SignedIn
from grader.pages.templates import TEMPLATES
from grader.services.setup import assignments as logic
from grader.services.setup import course_changes, courses, roster
from grader.services.lti import launch as lti
from grader.services.identity import sign_in_links
from grader.services.errors import Conflict, Invalid

router = APIRouter(include_in_schema=False)

DATES = ("open_at", "due_at", "hard_close_at")
OPTIONAL_NUMBERS = ("late_penalty_cap", "max_attempts", "max_per_hour")
CHOICES = ("title", "lesson", "part", "counted_attempt", "visibility")
LOCAL_INPUT = "%Y-%m-%dT%H:%M"  # what <input type="datetime-local"> sends and shows
ROSTER_MAX_BYTES = 1_000_000


async def form_data(request: Request) -> FormData:
    """The posted form as it came (the assignment form's per-item fields are as many as the lesson's items)."""
    return await request.form()


Posted = Annotated[FormData, Depends(form_data)]


# --- times typed in the course's zone ---------------------------------------------------------------------------

def instant(text: str, tz: str) -> datetime:
    """A datetime-local value typed in the course's zone, as an aware instant; ValueError saying what is wrong.
    A time the clocks skip (spring forward) is refused, never moved; one they repeat is the first of the two."""
    text = text.strip()
    if not text:
        raise ValueError(f"required: a date and time in {tz}")
    try:
        typed = datetime.fromisoformat(text)
    except ValueError:
        raise ValueError(f"{text!r} is not a date and time (YYYY-MM-DD HH:MM) in {tz}") from None
    if typed.tzinfo is not None:
        return typed
    aware = typed.replace(tzinfo=zone(tz))
    try:
        back = aware.astimezone(UTC).astimezone(zone(tz)).replace(tzinfo=None)
    except OverflowError:
        return aware  # the API's own rule names it: outside the representable range of dates
    if back != typed:
        raise ValueError(f"{text.replace('T', ' ')} does not exist in {tz}: the clocks skip it")
    return aware


def local_input(at: datetime | None, tz: str) -> str:
    """A stored naive-UTC time as a datetime-local value in the course's zone."""
    return at.replace(tzinfo=UTC).astimezone(zone(tz)).strftime(LOCAL_INPUT) if at else ""


def dates_from(posted: dict[str, str], names, tz: str) -> tuple[dict, list[dict[str, str]]]:
    """The named datetime-local fields as aware instants, and an error for each that is not one."""
    out, errors = {}, []
    for name in names:
        try:
            out[name] = instant(posted.get(name, ""), tz)
        except ValueError as exc:
            errors.append({"field": name, "rule": str(exc)})
    return out, errors


def checked_form(check, raw: dict, posted: dict[str, str], date_names, tz: str) -> dict:
    """`raw` with the named dates of `posted` (typed in the course's zone), checked by the service's `check`: Invalid
    with every error, the page's own about a date first, each naming its field."""
    when, errors = dates_from(posted, date_names, tz)
    try:
        fields = check(raw | when)
    except Invalid as exc:
        named = {e["field"] for e in errors}
        raise Invalid(exc.detail, errors + [e for e in exc.errors if e["field"] not in named]) from None
    if errors:
        raise Invalid("invalid form", errors)
    return fields


# --- the assignment form ------------------------------------------------------------------------------------------

def all_items(lesson: str = "L03") -> list[tuple[str, bool]]:
    """Every item of the lesson, and whether it is a concept checkpoint (the checkpoints part holds only those)."""
    checkpoints = set(logic.item_ids(lesson, AssignmentParts.CHECKPOINTS))
    return [(item, item in checkpoints) for item in logic.item_ids(lesson, AssignmentParts.SHEET)]


def typed(form: FormData) -> dict[str, str]:
    """The form's fields as typed (strings), kept to show the form again after a refusal."""
    return {k: v for k, v in form.items() if isinstance(v, str)}


def assignment_fields(posted: dict[str, str], tz: str) -> dict:
    """The form's values as the service's fields, checked by its rules (grader.services.setup.assignments.checked):
    Invalid with every error, each naming its field."""
    raw = {k: posted.get(k, "") for k in CHOICES}
    raw["late_penalty_per_day"] = posted.get("late_penalty_per_day", "").strip() or 0.0
    raw |= {k: posted.get(k, "").strip() or None for k in OPTIONAL_NUMBERS}
    raw["item_visibility"] = {item: shown for item, _ in all_items()
                              if (shown := posted.get(f"item_visibility.{item}", ""))}
    return checked_form(logic.checked, raw, posted, DATES, tz)


def assignment_values(a: Assignment) -> dict[str, str]:
    """An assignment's settings as the form's fields."""
    tz = a.course.timezone
    out = {k: str(getattr(a, k)) for k in CHOICES}
    out |= {k: local_input(getattr(a, k), tz) for k in DATES}
    out["late_penalty_per_day"] = f"{a.late_penalty_per_day:g}"
    out |= {k: "" if getattr(a, k) is None else f"{getattr(a, k):g}" for k in OPTIONAL_NUMBERS}
    out |= {f"item_visibility.{item}": shown for item, shown in (a.item_visibility or {}).items()}
    return out


NEW_VALUES = {"lesson": "L03", "part": AssignmentParts.SHEET, "counted_attempt": "latest",
              "visibility": Visibility.IMMEDIATE, "late_penalty_per_day": "0"}


# The form's labels for the API's field names a rule may mention ("due_at must be after open_at").
FORM_WORDS = {"hard_close_at": "“Hard close”", "due_at": "“Due”", "open_at": "“Opens”",
              "late_penalty_per_day": "“Late penalty per day late”", "late_penalty_cap": "“Late penalty cap”",
              "max_attempts": "“Attempts allowed”", "max_per_hour": "“Submissions in any 60 minutes”",
              "counted_attempt": "“The attempt that counts”", "item_visibility": "“Items shown otherwise”"}
_FORM_WORD = re.compile(r"\b(" + "|".join(FORM_WORDS) + r")\b")


def in_form_words(errors: list[dict[str, str]] | None) -> list[dict[str, str]]:
    """Each error's rule naming fields by the form's labels, not by the API's names (the field stays the API's: the
    page puts the error beside that field and names it by its label)."""
    return [e | {"rule": _FORM_WORD.sub(lambda m: FORM_WORDS[m[1]], e["rule"])} for e in errors or []]


def by_field(errors: list[dict[str, str]] | None) -> dict[str, list[str]]:
    out: dict[str, list[str]] = {}
    for e in errors or []:
        out.setdefault(e["field"], []).append(e["rule"])
    return out


def form_page(request: Request, session, user, course: Course, *, assignment: Assignment | None,
              posted: dict[str, str], errors: list[dict[str, str]] | None = None,
              status_code: int = status.HTTP_200_OK) -> HTMLResponse:
    submitted = logic.submission_count(session=session, assignment=assignment) if assignment else 0
    errors = in_form_words(errors)
    return TEMPLATES.TemplateResponse(request, "setup/assignment_form.html", {
        "user": user, "course": course, "a": assignment, "v": posted, "errors": errors or [],
        "field_errors": by_field(errors), "items": all_items(), "parts": values(AssignmentParts),
        "visibilities": values(Visibility), "submitted": submitted, "tz": course.timezone},
        status_code=status_code)


# --- the set-up page --------------------------------------------------------------------------------------------

def zone_names() -> list[str]:
    return sorted(n for n in available_timezones() if is_zone(n))


def setup_page(request: Request, session, user, course: Course, *, section: str | None = None,
               errors: list[dict[str, str]] | None = None, posted: dict[str, str] | None = None,
               status_code: int = status.HTTP_200_OK) -> HTMLResponse:
    """The set-up page; a refused form's errors (and what was typed) are shown in its `section`."""
    return TEMPLATES.TemplateResponse(request, "setup/courses.html", {
        "user": user, "course": course, "assignments": logic.of_course(session=session, course=course),
        "students": roster.students(session=session, course=course),
        "registrations": lti.course_registrations(session=session, course=course),
        "changes": course_changes.of_course(session=session, course=course), "zones": zone_names(),
        "section": section, "errors": errors or [], "v": posted or {}}, status_code=status_code)


@router.get("/courses/{course}/setup", response_class=HTMLResponse)
def setup(request: Request, row: InstructorCourse, session: SessionDep, user: SignedIn):
    return setup_page(request, session, user, row)


@router.post("/courses/{course}/setup/timezone", response_class=HTMLResponse)
def set_timezone(request: Request, row: InstructorCourse, session: SessionDep, user: SignedIn,
                 timezone: str = Form("")):
    try:
        courses.update_settings(session=session, course=row, by=user, timezone=timezone.strip())
    except Invalid as exc:
        session.rollback()
        return setup_page(request, session, user, row, section="timezone", errors=exc.errors,
                          posted={"timezone": timezone}, status_code=status.HTTP_422_UNPROCESSABLE_CONTENT)
    return RedirectResponse(f"/courses/{row.name}/setup#timezone", status_code=status.HTTP_303_SEE_OTHER)


@router.post("/courses/{course}/setup/free-submissions", response_class=HTMLResponse)
def set_free_submissions(row: InstructorCourse, session: SessionDep, user: SignedIn,
                         free_submissions: str = Form("")):
    """Whether the course's students may submit outside an assignment (an unchecked box sends nothing: refused)."""
    courses.update_settings(session=session, course=row, by=user, free_submissions=bool(free_submissions))
    return RedirectResponse(f"/courses/{row.name}/setup#free-submissions", status_code=status.HTTP_303_SEE_OTHER)


def roster_text(upload: UploadFile | None) -> str:
    """The uploaded file as text (a spreadsheet's UTF-8 byte order mark dropped); Invalid naming `csv` otherwise."""
    data = upload.file.read(ROSTER_MAX_BYTES + 1) if upload is not None else b""
    if not data:
        raise Invalid("invalid roster", [{"field": "csv", "rule": "choose a CSV file (student_id,name,email)"}])
    if len(data) > ROSTER_MAX_BYTES:
        raise Invalid("invalid roster", [{"field": "csv", "rule": f"at most {ROSTER_MAX_BYTES} bytes"}])
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError:
        raise Invalid("invalid roster", [{"field": "csv", "rule": "UTF-8 text (save the sheet as \"CSV UTF-8\")"}]) \
            from None


def link_url(request: Request, secret: str) -> str:
    """The page a student opens: this site's address, as the instructor reached it."""
    return str(request.base_url).rstrip("/") + sign_in_links.PATH + secret


def issued_page(request: Request, user, course: Course, rows: list[dict], *, links: bool, what: str) -> HTMLResponse:
    """The one answer that shows new tokens and links: nothing keeps them but this page and its CSV."""
    stamp = utcnow().strftime("%Y%m%d-%H%M%S")
    return TEMPLATES.TemplateResponse(request, "setup/roster_issued.html", {
        "user": user, "course": course, "rows": rows, "links": links, "what": what,
        "csv": roster.issued_csv(rows), "filename": f"{course.name}-issued-{stamp}.csv",
        "secrets": any(r.get("token") or r.get("sign_in_link") for r in rows)})


@router.post("/courses/{course}/setup/roster", response_class=HTMLResponse)
def upload_roster(request: Request, row: InstructorCourse, session: SessionDep, user: SignedIn,
                  csv: UploadFile | None = File(None), links: str = Form("")):
    try:
        entries = roster.import_csv(session=session, course=row, text=roster_text(csv), by=user, links=bool(links))
    except Invalid as exc:
        session.rollback()
        return setup_page(request, session, user, row, section="roster", errors=exc.errors,
                          posted={"links": links}, status_code=status.HTTP_422_UNPROCESSABLE_CONTENT)
    rows = [{**e, "sign_in_link": link_url(request, e["link_secret"]) if e["link_secret"] else None,
             "expires_at": e["link_expires_at"]} for e in entries]
    return issued_page(request, user, row, rows, links=bool(links), what="roster")


@router.post("/courses/{course}/setup/students/{student}/sign-in-link", response_class=HTMLResponse)
def new_sign_in_link(request: Request, row: InstructorCourse, student: str, session: SessionDep, user: SignedIn):
    try:
        secret, link = sign_in_links.issue_for(session=session, course=row, student_name=student, by=user)
    except Invalid as exc:
        session.rollback()
        return setup_page(request, session, user, row, section="students", errors=exc.errors,
                          status_code=status.HTTP_422_UNPROCESSABLE_CONTENT)
    person = link.user
    rows = [{"student": person.name, "name": person.full_name, "email": person.email, "created": False,
             "token": None, "sign_in_link": link_url(request, secret), "expires_at": link.expires_at}]
    return issued_page(request, user, row, rows, links=True, what="link")


# --- creating and editing an assignment ---------------------------------------------------------------------------

@router.get("/courses/{course}/setup/assignments/new", response_class=HTMLResponse)
def new_assignment(request: Request, row: InstructorCourse, session: SessionDep, user: SignedIn):
    return form_page(request, session, user, row, assignment=None, posted=dict(NEW_VALUES))


@router.post("/courses/{course}/setup/assignments", response_class=HTMLResponse)
def create_assignment(request: Request, row: InstructorCourse, session: SessionDep, user: SignedIn, form: Posted):
    posted = typed(form)
    try:
        made = logic.create(session=session, course=row, user=user, fields=assignment_fields(posted, row.timezone))
    except Invalid as exc:
        session.rollback()
        return form_page(request, session, user, row, assignment=None, posted=posted, errors=exc.errors,
                         status_code=status.HTTP_422_UNPROCESSABLE_CONTENT)
    return RedirectResponse(f"/assignments/{made.id}", status_code=status.HTTP_303_SEE_OTHER)


@router.get("/assignments/{assignment_id}/edit", response_class=HTMLResponse)
def edit_assignment(request: Request, assignment: InstructorsAssignment, session: SessionDep, user: SignedIn):
    return form_page(request, session, user, assignment.course, assignment=assignment,
                     posted=assignment_values(assignment))


@router.post("/assignments/{assignment_id}/edit", response_class=HTMLResponse)
def save_assignment(request: Request, assignment: InstructorsAssignment, session: SessionDep, user: SignedIn,
                    form: Posted):
    posted = typed(form)
    course = assignment.course
    try:
        logic.update(session=session, assignment=assignment, by=user,
                     fields=assignment_fields(posted, course.timezone))
    except (Invalid, Conflict) as exc:  # Conflict: a part fixed by the submissions already made
        session.rollback()
        return form_page(request, session, user, course, assignment=assignment, posted=posted, errors=exc.errors,
                         status_code=status.HTTP_409_CONFLICT if isinstance(exc, Conflict)
                         else status.HTTP_422_UNPROCESSABLE_CONTENT)
    return RedirectResponse(f"/assignments/{assignment.id}", status_code=status.HTTP_303_SEE_OTHER)
