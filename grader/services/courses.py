"""A course's settings: its time zone (times stay stored in UTC; pages and refusal messages show them in it)."""

from __future__ import annotations

from sqlalchemy.orm import Session

from grader.core.timezones import is_zone
from grader.models import Course
from grader.services.errors import Invalid


def set_timezone(*, session: Session, course: Course, timezone: str) -> Course:
    """Set the course's IANA time zone (Invalid naming the field for an unknown one). Commits."""
    if not is_zone(timezone):
        raise Invalid("invalid course settings", [{"field": "timezone", "rule": (
            f"{timezone!r} is not an IANA time zone name (e.g. UTC, Europe/Berlin, America/New_York)")}])
    course.timezone = timezone
    session.commit()
    return course
