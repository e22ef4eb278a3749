"""Scores sent to the LMS gradebooks on their own: what changed is marked in the change's transaction
(`scores_changed`, the core's half), the reconciler's pass sends what is due (`send_due`), a failure backs off and
stays visible on the instructor's LTI page (`course_overview`), and an instructor may retry at once (`retry_now`).

What is sent is `grader.services.lti.launch.send_scores`'s: each LMS student's counted score as they may see it, only where
it differs from the last score sent (idempotent), and nothing for a student with any item still withheld (the total
would tell the hidden items; the release or the due date sends it)."""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from datetime import datetime, timedelta

from sqlalchemy import case, select, update
from sqlalchemy.orm import Session

from grader.core.lti_outbox import mark, scores_changed
from grader.core.states import Visibility
from grader.core.models import (Assignment, Course, LtiContext, LtiLineItem, LtiOutbox, LtiRegistration, LtiScore,
                           User, utcnow)
from grader.services.lti import launch as lti
from grader.services.setup.assignments import counted_grades, dates_for, item_ids
from grader.services.submissions.visibility import visibility_of
from grader.core.settings import settings

__all__ = ["scores_changed", "send_due", "retry_now", "course_overview", "backoff", "OutboxPass", "LtiOverview"]

# The first retry after a failed pass, doubled after each further failure up to the cap: a platform that is down
# for an hour is asked about a dozen times, not every pass.
BACKOFF_FIRST_S = 60.0
BACKOFF_MAX_S = 3600.0
# A pass claims a row for this long: a sender that died mid-send leaves it to be tried again after it.
CLAIM_S = 300.0
# At most this many assignments per pass: the reconciler's own work must not wait behind a long send.
PER_PASS = 20

log = logging.getLogger(__name__)


def backoff(attempts: int) -> timedelta:
    """How long after its `attempts`-th failed pass in a row an assignment is tried again."""
    return timedelta(seconds=min(BACKOFF_FIRST_S * 2 ** max(attempts - 1, 0), BACKOFF_MAX_S))


@dataclass(frozen=True)
class OutboxPass:
    """One assignment's send in a pass: how many scores went, were unchanged, failed or wait (withheld)."""

    assignment_id: int
    counts: dict[str, int] = field(default_factory=dict)
    error: str | None = None
    next_try_at: datetime | None = None


def _claim(session: Session, now: datetime, only: list[int] | None) -> list[tuple[int, datetime]]:
    """The due rows, each pushed CLAIM_S out and committed before any request leaves: a grade stored meanwhile
    marks its row without waiting on this pass's sends. Rows another pass holds are skipped."""
    query = select(LtiOutbox).where(LtiOutbox.due_at <= now).order_by(LtiOutbox.due_at).limit(PER_PASS)
    if only is not None:
        query = query.where(LtiOutbox.assignment_id.in_(only))
    rows = list(session.scalars(query.with_for_update(skip_locked=True)))
    claimed = [(row.assignment_id, row.changed_at) for row in rows]
    for row in rows:
        row.due_at, row.tried_at = now + timedelta(seconds=CLAIM_S), now
    session.commit()
    return claimed


def _next_reveal(session: Session, assignment: Assignment, now: datetime) -> datetime | None:
    """When a withheld score may next become sendable without any change being marked: the earliest due date
    (extensions included) still ahead, where an item is shown after the due date. A release marks its own change."""
    if Visibility.AFTER_DUE not in {visibility_of(assignment, i) for i in item_ids(assignment.lesson,
                                                                                     assignment.part)}:
        return None
    ahead = [d for c in counted_grades(session=session, assignment=assignment)
             if (d := dates_for(session=session, assignment=assignment, student=c.submission.student).due_at) > now]
    return min(ahead, default=None)


def _send_one(session: Session, assignment_id: int, seen: datetime, now: datetime, report_url: str) -> OutboxPass:
    """Sends one claimed assignment and records the outcome on its row (committed)."""
    assignment = session.get(Assignment, assignment_id)
    try:
        results = lti.send_scores(session=session, assignment=assignment, report_url=report_url)
        session.commit()
    except Exception as exc:  # noqa: BLE001 - any failure is recorded and retried, never lost or hidden
        session.rollback()
        log.exception("sending the scores of assignment %s to the LMS failed", assignment_id)
        results, crash = [], f"{type(exc).__name__}: {lti.failure_text(exc)}"[:1000]
    else:
        crash = None
    counts: dict[str, int] = {}
    for r in results:
        counts[r.status] = counts.get(r.status, 0) + 1
    failed = [r for r in results if r.status == "failed"]
    error = crash or (f"{len(failed)} of {len(results)} scores failed: {failed[0].error}" if failed else None)
    waiting = (f"{counts['withheld']} student(s) get no score while an item is withheld from them"
               if counts.get("withheld") else None)
    row = session.scalar(select(LtiOutbox).where(LtiOutbox.assignment_id == assignment_id))
    if error:
        attempts = row.attempts + 1
        values = dict(attempts=attempts, due_at=now + backoff(attempts), last_error=error, waiting=waiting)
    else:
        reveal = _next_reveal(session, assignment, now) if waiting else None
        # A change marked while this pass was sending is sent by the next pass.
        values = dict(attempts=0, last_error=None, waiting=waiting,
                      due_at=case((LtiOutbox.changed_at > seen, now), else_=reveal))
    session.execute(update(LtiOutbox).where(LtiOutbox.id == row.id).values(**values))
    session.commit()
    session.refresh(row)
    return OutboxPass(assignment_id, counts, error, row.due_at)


def send_due(*, session: Session, now: datetime | None = None, report_url: str | None = None,
             assignment_ids: list[int] | None = None) -> list[OutboxPass]:
    """Sends every assignment whose scores are due (of `assignment_ids` only, where given): the reconciler's pass
    and an instructor's retry. `report_url` is the report's URL with `{id}`; by default from PUBLIC_URL. Commits."""
    now = now or utcnow()
    if report_url is None:
        report_url = settings.public_url.rstrip("/") + "/submissions/{id}" if settings.public_url else ""
    return [_send_one(session, assignment_id, seen, now, report_url)
            for assignment_id, seen in _claim(session, now, assignment_ids)]


def retry_now(*, session: Session, course: Course, report_url: str | None = None) -> list[OutboxPass]:
    """An instructor's "retry now": every assignment of the course with a failed or pending send (a failed score, or
    a backing-off or due row) is sent at once, whatever its backoff. Commits."""
    ids = set(session.scalars(select(LtiOutbox.assignment_id).join(Assignment)
                              .where(Assignment.course_id == course.id, LtiOutbox.due_at.is_not(None))))
    ids |= set(session.scalars(select(LtiLineItem.assignment_id).join(LtiScore)
                               .join(Assignment, Assignment.id == LtiLineItem.assignment_id)
                               .where(Assignment.course_id == course.id, LtiScore.status == "failed")))
    now = utcnow()
    mark(session=session, assignment_ids=list(ids), now=now)
    session.execute(update(LtiOutbox).where(LtiOutbox.assignment_id.in_(ids)).values(due_at=now))
    session.commit()
    return send_due(session=session, now=now, report_url=report_url, assignment_ids=list(ids))


# --- what the instructor's LTI page shows --------------------------------------------------------------------------

@dataclass(frozen=True)
class ScoreRow:
    student: str
    full_name: str | None
    score: float
    maximum: float
    status: str  # sent | failed
    error: str | None
    tries: int
    sent_at: datetime


@dataclass(frozen=True)
class LineItemRow:
    assignment: Assignment
    context: str
    url: str
    scores: list[ScoreRow]


@dataclass(frozen=True)
class LtiOverview:
    registrations: list
    contexts: list[LtiContext]
    line_items: list[LineItemRow]
    outbox: list[LtiOutbox]  # rows with something due, backing off, or waiting on withheld items

    @property
    def failed(self) -> list[tuple[LineItemRow, ScoreRow]]:
        return [(item, s) for item in self.line_items for s in item.scores if s.status == "failed"]


def course_overview(*, session: Session, course: Course) -> LtiOverview:
    """The course's registrations, LMS courses, line items with the last score sent to each student, and the sends
    still due or failing (with their error and next retry), for the instructor's LTI page."""
    registrations = lti.course_registrations(session=session, course=course)
    contexts = list(session.scalars(select(LtiContext).join(LtiRegistration)
                                    .where(LtiRegistration.course_id == course.id).order_by(LtiContext.id)))
    items = []
    for item in session.scalars(select(LtiLineItem).join(Assignment)
                                .where(Assignment.course_id == course.id).order_by(LtiLineItem.id)):
        scores = [ScoreRow(user.name, user.full_name, s.score_given, s.score_maximum, s.status, s.error,
                           s.tries, s.sent_at)
                  for s, user in session.execute(select(LtiScore, User).join(User, User.id == LtiScore.user_id)
                                                 .where(LtiScore.line_item_id == item.id).order_by(User.name))]
        context = session.get(LtiContext, item.context_id)
        items.append(LineItemRow(session.get(Assignment, item.assignment_id), context.context_id, item.url, scores))
    outbox = list(session.scalars(select(LtiOutbox).join(Assignment).where(
        Assignment.course_id == course.id,
        (LtiOutbox.due_at.is_not(None)) | (LtiOutbox.last_error.is_not(None)) | (LtiOutbox.waiting.is_not(None)))
        .order_by(LtiOutbox.assignment_id)))
    return LtiOverview(registrations, contexts, items, outbox)
