"""A course's settings: its time zone (times stay stored in UTC; pages and refusal messages show them in it) and
whether its students may submit outside an assignment (grader.services.submissions.submit)."""

from __future__ import annotations

from sqlalchemy.orm import Session

from grader.core.timezones import is_zone
from grader.models import Course
from grader.services.errors import Invalid


def update_settings(*, session: Session, course: Course, timezone: str | None = None,
                    free_submissions: bool | None = None) -> Course:
    """Change the settings given (None keeps one): all or nothing, Invalid naming the field for an unknown zone.
    Commits."""
    if timezone is not None and not is_zone(timezone):
        raise Invalid("invalid course settings", [{"field": "timezone", "rule": (
            f"{timezone!r} is not an IANA time zone name (e.g. UTC, Europe/Berlin, America/New_York)")}])
    if timezone is not None:
        course.timezone = timezone
    if free_submissions is not None:
        course.free_submissions = free_submissions
    session.commit()
    return course
