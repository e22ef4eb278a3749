"""Rubric versions as rows, and which version a course grades under: shared by the API and the worker.

Every version the service knows is a `RubricVersion` row holding its whole content: the files shipped in
rubric/lessons are recorded as "shipped" (no publisher, no course, read by every course), and an instructor publishes
new ones for their own course through the API (`publish`, under rubric.governance's rules), which no other course
sees and nobody changes after. A course grades new submissions under the version its latest committed
regrade chose, else under the newest shipped version.
"""

from __future__ import annotations

from sqlalchemy import select
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from rubric.governance import RubricGovernanceError, publish_version, rubric_changes
from rubric.rubrics import load_rubric, parse_rubric, rubric_versions, shipped_hash, version_key

from grader.core.models import Grade, Regrade, RubricVersion, User


# Stored rubric versions parsed and checked against their hash once per process, by that hash: a stored version's
# content is never edited, and parsing it with its hash check took ~5 ms of every report page view.
_PARSED: dict[tuple[str, str, str], object] = {}


def _row_rubric(row: RubricVersion):
    """The row's Rubric (frozen; shared between callers, who must not change its lists)."""
    key = (row.lesson, row.version, row.content_hash)
    if key in _PARSED:
        return _PARSED[key]
    rubric = parse_rubric(row.content)
    if rubric.content_hash != row.content_hash:  # stored content is never edited; a mismatch is corruption
        raise ValueError(f"rubric {row.lesson} v{row.version}: stored content does not match its hash "
                         f"{row.content_hash[:12]}")
    _PARSED[key] = rubric
    return rubric


def sync_shipped(session: Session, lesson: str) -> list[RubricVersion]:
    """Record every shipped file version of `lesson` not yet known (flushes); returns the shipped rows, oldest first.

    A shipped file whose content differs from its recorded row is refused by governance when any grade used that
    version (a used version is immutable) and otherwise replaces the row.
    """
    rows = {r.version: r for r in session.scalars(select(RubricVersion).where(RubricVersion.lesson == lesson,
                                                                              RubricVersion.course_id.is_(None)))}
    for version in rubric_versions(lesson):
        row = rows.get(version)
        if row is not None and row.content_hash == shipped_hash(lesson, version):
            continue
        shipped = load_rubric(lesson, version)
        if row is not None:
            publish_version(shipped, [_row_rubric(r) for r in rows.values()], used_versions(session, lesson))
            row.content, row.content_hash = shipped.model_dump(mode="json"), shipped.content_hash
            continue
        rows[version] = _record_shipped(session, shipped)
    session.flush()
    return sorted(rows.values(), key=lambda r: version_key(r.version))


def _record_shipped(session: Session, shipped) -> RubricVersion:
    """The row of a shipped version seen for the first time. Two API processes taking their first submissions at
    once both find it missing: the second insert meets the unique index (uq_rubric_versions_shipped) and reads the
    first one's row instead of failing the submission."""
    row = RubricVersion(lesson=shipped.lesson, version=shipped.version, content_hash=shipped.content_hash,
                        content=shipped.model_dump(mode="json"), source="shipped")
    try:
        with session.begin_nested():
            session.add(row)
    except IntegrityError:
        row = session.scalar(select(RubricVersion).where(RubricVersion.lesson == shipped.lesson,
                                                         RubricVersion.version == shipped.version,
                                                         RubricVersion.course_id.is_(None)))
        if row is None or row.content_hash != shipped.content_hash:
            raise
    return row


def course_versions(session: Session, course_id: int, lesson: str) -> list[RubricVersion]:
    """The versions of `lesson` a course may read and grade under, oldest first: the shipped ones (recorded on first
    sight, flushes) and the course's own published ones. Where a later shipped file takes a version string the course
    had published, the course's own row stands for it."""
    rows = {r.version: r for r in sync_shipped(session, lesson)}
    rows |= {r.version: r for r in session.scalars(select(RubricVersion).where(RubricVersion.lesson == lesson,
                                                                               RubricVersion.course_id == course_id))}
    return sorted(rows.values(), key=lambda r: version_key(r.version))


def used_versions(session: Session, lesson: str) -> set[str]:
    return set(session.scalars(select(Grade.rubric_version).where(Grade.rubric_lesson == lesson).distinct()))


def _course_row(session: Session, course_id: int, lesson: str, version: str) -> RubricVersion:
    """The row of `lesson` at `version` as the course reads it; LookupError naming the versions the course may read
    (another course's are never named) if there is none."""
    rows = course_versions(session, course_id, lesson)
    row = next((r for r in rows if r.version == version), None)
    if row is None:
        known = ", ".join(r.version for r in rows) or "none"
        raise LookupError(f"lesson {lesson} has no rubric version {version!r}; known: {known}")
    return row


def get_version(session: Session, lesson: str, version: str, *, course_id: int):
    """The stored Rubric of `lesson` at `version` as the course reads it; LookupError if the course has none."""
    return _row_rubric(_course_row(session, course_id, lesson, version))


def stored_version(session: Session, lesson: str, version: str, content_hash: str):
    """The Rubric stored for `lesson` at `version` with that content hash (a grade's), or None; reads only (no shipped
    file is parsed or recorded), for the pages: a grade's version was stored when the grade was. The hash picks the
    content the grade used, whichever course published it: two courses may each have a different v3."""
    row = session.scalar(select(RubricVersion).where(RubricVersion.lesson == lesson, RubricVersion.version == version,
                                                     RubricVersion.content_hash == content_hash).limit(1))
    return None if row is None else _row_rubric(row)


def publish(session: Session, *, content: dict, user: User) -> RubricVersion:
    """Record a rubric version published by `user` for their course (flushes). Raises pydantic's ValidationError for
    a malformed rubric and rubric.governance.RubricGovernanceError for one refused: a version string shipped with the
    service, a change to a version the course already published (published versions never change), a changed
    tolerance without a new review. Republishing identical content returns the existing row."""
    new = parse_rubric(content)
    rows = course_versions(session, user.course_id, new.lesson)
    prior = next((r for r in rows if r.version == new.version), None)
    if prior is not None and prior.course_id is None:
        raise RubricGovernanceError(f"rubric {new.lesson} version {new.version} is shipped with the service and "
                                    "cannot be published over; publish a new version")
    if prior is not None and prior.content_hash == new.content_hash:
        return prior
    if prior is not None:
        raise RubricGovernanceError(
            f"rubric {new.lesson} version {new.version} is published and immutable (stored hash "
            f"{prior.content_hash[:12]}, new {new.content_hash[:12]}); changes: "
            f"{', '.join(rubric_changes(_row_rubric(prior), new)) or 'content'}; publish them as a new version")
    publish_version(new, [_row_rubric(r) for r in rows], set())
    row = RubricVersion(course_id=user.course_id, lesson=new.lesson, version=new.version,
                        content_hash=new.content_hash, content=new.model_dump(mode="json"), source="published",
                        published_by_id=user.id)
    session.add(row)
    session.flush()
    return row


def course_version(session: Session, course_id: int, lesson: str) -> str:
    """The rubric version a course grades `lesson` under: its latest committed regrade's, else the newest shipped."""
    committed = session.scalar(select(Regrade.version).where(Regrade.course_id == course_id, Regrade.lesson == lesson)
                               .order_by(Regrade.id.desc()).limit(1))
    if committed is not None:
        return committed
    shipped = rubric_versions(lesson)
    if not shipped:
        raise LookupError(f"no rubric files for lesson {lesson!r}")
    return shipped[-1]


def course_rubric(session: Session, course_id: int, lesson: str):
    """The Rubric new submissions of this course's lesson are graded under: a shipped version or the course's own."""
    return get_version(session, lesson, course_version(session, course_id, lesson), course_id=course_id)
