"""A course's settings: its time zone (times stay stored in UTC; pages and refusal messages show them in it) and
whether its students may submit outside an assignment (grader.services.submissions.submit.submit). A change is recorded
with who made it (grader.services.setup.course_changes)."""

from __future__ import annotations

from sqlalchemy.orm import Session

from grader.core.timezones import is_zone
from grader.core.models import Course, User
from grader.services.setup import course_changes
from grader.services.identity.access import require_course_instructor
from grader.services.setup.course_changes import ChangeKind
from grader.services.errors import Invalid


def update_settings(*, session: Session, course: Course, by: User, timezone: str | None = None,
                    free_submissions: bool | None = None) -> Course:
    """Change the settings given (None keeps one): all or nothing, Invalid naming the field for an unknown zone; a
    change is recorded with who made it. NotFound outside the course, Forbidden for anyone but its instructors.
    Commits."""
    require_course_instructor(by, course.id, action="change a course's settings", thing=f"course {course.name!r}")
    if timezone is not None and not is_zone(timezone):
        raise Invalid("invalid course settings", [{"field": "timezone", "rule": (
            f"{timezone!r} is not an IANA time zone name (e.g. UTC, Europe/Berlin, America/New_York)")}])
    changed = {}
    if timezone is not None and timezone != course.timezone:
        changed["timezone"] = [course.timezone, timezone]
        course.timezone = timezone
    if free_submissions is not None and free_submissions != course.free_submissions:
        changed["free_submissions"] = [course.free_submissions, free_submissions]
        course.free_submissions = free_submissions
    if changed:
        course_changes.record(session=session, course=course, by=by, kind=ChangeKind.COURSE_SETTINGS,
                              summary=_settings_summary(changed), detail=changed)
    session.commit()
    return course


def _settings_summary(changed: dict[str, list]) -> str:
    parts = []
    if "timezone" in changed:
        parts.append("time zone {} → {}".format(*changed["timezone"]))
    if "free_submissions" in changed:
        parts.append("submissions outside assignments {} → {}".format(
            *("allowed" if v else "refused" for v in changed["free_submissions"])))
    return "; ".join(parts)
