"""Roster import: a course's students from CSV (student id, name, email), each new one given a token once, and on
request each student in the file a fresh sign-in link (grader.services.identity.sign_in_links); each import recorded with who
made it (grader.services.setup.course_changes), by an instructor of the course only (checked here, not only by the page or
route). A file's rows and fields are capped before any work, and any line ending (CRLF, LF, CR) is read; a line the
csv reader refuses is named, never a 500."""

from __future__ import annotations

import csv
import io
import re

from sqlalchemy import select
from sqlalchemy.orm import Session

from grader.core.states import Role
from grader.core.models import Course, User
from grader.services.identity import accounts, sign_in_links
from grader.services.setup import course_changes
from grader.services.identity.access import require_instructor
from grader.services.setup.course_changes import ChangeKind
from grader.services.errors import Invalid, NotFound
from rubric.exports import csv_text

COLUMNS = ["student_id", "name", "email"]
STUDENT_ID = re.compile(r"^[A-Za-z0-9_.@\-]{1,64}$")
EMAIL = re.compile(r"^[^@\s]{1,64}@[^@\s]+\.[^@\s]+$")
# A class is hundreds of students; a field is at most an email's 254 characters. Longer is refused before any work.
MAX_ROWS = 5000
MAX_FIELD = 1000
MAX_ERRORS = 20


def parse_roster(text: str) -> tuple[list[tuple[str, str, str]], list[dict[str, str]]]:
    """The rows, and every error as {field: 'csv.line N.COLUMN', rule} (the first MAX_ERRORS); nothing is stored while
    any error stands. Lines end in CRLF, LF or CR alike (newline="": the csv module's own line handling)."""
    reader = csv.reader(io.StringIO(text, newline=""))
    try:
        header = [h.strip() for h in next(reader, [])]
    except csv.Error as exc:
        return [], [_unreadable(reader, exc)]
    if header != COLUMNS:
        shown = ",".join(header)
        shown = shown if len(shown) <= 200 else shown[:200] + "..."
        return [], [{"field": "csv.line 1", "rule": f"the header must be {','.join(COLUMNS)}, got {shown}"}]
    rows, errors, seen = [], [], set()
    try:
        for line, row in enumerate(reader, start=2):
            if len(errors) >= MAX_ERRORS:
                break
            if line - 1 > MAX_ROWS:
                errors.append({"field": f"csv.line {line}", "rule": f"at most {MAX_ROWS} student rows in one file"})
                break
            _row(line, row, rows, errors, seen)
    except csv.Error as exc:  # a field past the csv module's limit, a NUL byte: named, never a 500
        errors.append(_unreadable(reader, exc))
    if not rows and not errors:
        errors.append({"field": "csv", "rule": "no student rows"})
    return rows, errors


def _unreadable(reader, exc: csv.Error) -> dict[str, str]:
    return {"field": f"csv.line {reader.line_num}", "rule": f"not readable as CSV: {exc}"}


def _row(line: int, row: list[str], rows: list, errors: list, seen: set) -> None:
    """One record: its errors appended to `errors`, or it to `rows` (a blank line is skipped)."""
    if not any(cell.strip() for cell in row):
        return
    if len(row) != 3:
        errors.append({"field": f"csv.line {line}", "rule": f"3 columns expected, got {len(row)}"})
        return
    if too_long := [COLUMNS[i] for i, cell in enumerate(row) if len(cell) > MAX_FIELD]:
        errors.extend({"field": f"csv.line {line}.{column}", "rule": f"at most {MAX_FIELD} characters"}
                      for column in too_long)
        return
    sid, name, email = (cell.strip() for cell in row)
    if not STUDENT_ID.match(sid):
        errors.append({"field": f"csv.line {line}.student_id",
                       "rule": "1-64 letters, digits or _.@- (it becomes the student's name in the service)"})
    elif sid in seen:
        errors.append({"field": f"csv.line {line}.student_id", "rule": f"{sid!r} appears twice in the file"})
    if not 1 <= len(name) <= 128:
        errors.append({"field": f"csv.line {line}.name", "rule": "1 to 128 characters"})
    if len(email) > 254 or not EMAIL.match(email):
        errors.append({"field": f"csv.line {line}.email", "rule": "an email address (name@domain)"})
    seen.add(sid)
    rows.append((sid, name, email))


def import_roster(*, session: Session, course: Course, rows: list[tuple[str, str, str]],
                  links: bool = False) -> list[dict]:
    """Add the students not yet in the course (each with a new token) and update the others' name and email; a
    re-import therefore never duplicates anyone or issues a second token. With `links`, every student of the file
    gets a new sign-in link secret (their earlier link stops working). The caller commits."""
    out = []
    for sid, name, email in rows:
        user = session.scalar(select(User).where(User.course_id == course.id, User.name == sid))
        created = user is None
        if created:
            user = accounts.get_or_create_user(session=session, course=course, name=sid, role="student")
        user.full_name, user.email = name, email
        token = accounts.create_token(session=session, user=user) if created else None
        link = sign_in_links.issue(session=session, user=user) if links else None
        out.append({"student": sid, "name": name, "email": email, "created": created, "token": token,
                    "link_secret": link[0] if link else None, "link_expires_at": link[1].expires_at if link else None})
    return out


def role_conflicts(*, session: Session, course: Course, rows: list[tuple[str, str, str]]) -> list[dict[str, str]]:
    """Rows naming someone of the course who is not a student (an instructor or auditor)."""
    staff = set(session.scalars(select(User.name).where(User.course_id == course.id, User.role != Role.STUDENT)))
    return [{"field": f"csv.student_id {sid}", "rule": f"{sid!r} is on the course staff, not a student"}
            for sid, _, _ in rows if sid in staff]


def import_csv(*, session: Session, course: Course, text: str, by: User, links: bool = False) -> list[dict]:
    """Import a roster CSV (student_id,name,email) into the course, all rows or none (Invalid naming each bad row's
    field and rule); new students get a token (and with `links` every row a sign-in link), shown only in the
    answer. Recorded with who imported it (names only, never a token or link). Commits. NotFound for anyone outside
    the course, Forbidden for a student or auditor of it, checked before the file is read."""
    if by.course_id != course.id:
        raise NotFound(f"course {course.name!r} not found")
    require_instructor(by, action="import the course's roster")
    rows, problems = parse_roster(text)
    problems = problems or role_conflicts(session=session, course=course, rows=rows)
    if problems:
        raise Invalid("invalid roster", problems)
    entries = import_roster(session=session, course=course, rows=rows, links=links)
    _record(session=session, course=course, by=by, entries=entries, links=links)
    session.commit()
    return entries


def _record(*, session: Session, course: Course, by: User, entries: list[dict], links: bool) -> None:
    created = [e["student"] for e in entries if e["created"]]
    updated = [e["student"] for e in entries if not e["created"]]
    summary = f"roster imported: {len(created)} new{_names(created)}, {len(updated)} updated{_names(updated)}"
    if links:
        summary += f"; new sign-in links for all {len(entries)} (earlier links revoked)"
    course_changes.record(session=session, course=course, by=by, kind=ChangeKind.ROSTER_IMPORTED, summary=summary,
                          detail={"created": created, "updated": updated, "links": links})


def _names(names: list[str], shown: int = 8) -> str:
    if not names:
        return ""
    more = f", and {len(names) - shown} more" if len(names) > shown else ""
    return f" ({', '.join(names[:shown])}{more})"


def students(*, session: Session, course: Course) -> list[User]:
    """The course's students, by name (student id)."""
    return list(session.scalars(select(User).where(User.course_id == course.id, User.role == Role.STUDENT)
                                .order_by(User.name)))


def issued_csv(rows: list[dict]) -> str:
    """What was issued, as the CSV an instructor keeps: student_id, token (new students only) and sign-in link (when
    one was issued); the only copy, since the service keeps only their hashes. Through the one safe CSV writer (a
    student id or name a spreadsheet would evaluate is neutralised; tokens and links never start like a formula)."""
    return csv_text([("student_id", "name", "email", "token", "sign_in_link")] + [
        (row["student"], row.get("name") or "", row.get("email") or "", row.get("token") or "",
         row.get("sign_in_link") or "") for row in rows])
