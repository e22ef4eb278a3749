"""Review requests: a student asks an instructor to review one item of their graded submission, with a message; an
instructor answers, with or without an override (grader.services.submissions.overrides), and the student reads the answer on
the report. A request is open until answered; at most one is open per item; answered ones are kept and listed.

A student asks only about an item shown to them (grader.services.submissions.visibility): a withheld item has no score yet to
question, and a request about it would tell staff nothing the release will not.
"""

from __future__ import annotations

from datetime import datetime

from pydantic import BaseModel
from sqlalchemy import select
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from grader.core.models import ReviewRequest, Submission, User, utcnow
from grader.core.schemas import UtcDateTime
from grader.services.identity import quotas
from grader.services.identity.access import MAX_ID, require_instructor
from grader.services.errors import Conflict, Forbidden, Invalid, NotFound
from grader.services.submissions.overrides import MAX_COMMENT, set_override
from grader.services.submissions.visibility import grade_view
from grader.core.settings import settings
from grader.services.identity import access

MAX_MESSAGE = 2000
STATES = ("open", "answered", "all")


class ReviewRequestPublic(BaseModel):
    id: int
    submission_id: int
    item_id: str
    student: str
    message: str
    created_at: UtcDateTime
    state: str  # open | answered
    answer: str | None
    answered_by: str | None
    answered_at: UtcDateTime | None
    override_id: int | None
    override_score: float | None


def state_of(request: ReviewRequest) -> str:
    return "open" if request.answered_at is None else "answered"


def public(request: ReviewRequest) -> ReviewRequestPublic:
    return ReviewRequestPublic(
        id=request.id, submission_id=request.submission_id, item_id=request.item_id, student=request.student.name,
        message=request.message, created_at=request.created_at, state=state_of(request), answer=request.answer,
        answered_by=request.answered_by.name if request.answered_by else None, answered_at=request.answered_at,
        override_id=request.override_id, override_score=request.override.score if request.override else None)


def _text(value: str | None, field: str, limit: int, why: str) -> tuple[str, list[dict[str, str]]]:
    text = (value or "").strip()
    if not text:
        return text, [{"field": field, "rule": f"required: {why}"}]
    if len(text) > limit:
        return text, [{"field": field, "rule": f"at most {limit} characters (this one has {len(text)})"}]
    return text, []


# --- asking -------------------------------------------------------------------------------------------------------

def ask(*, session: Session, submission: Submission, user: User, item_id: str, message: str,
        now: datetime | None = None) -> ReviewRequest:
    """A student asks for a review of one item of their own graded submission (commits).

    NotFound for another student's or course's submission, Forbidden for staff, Conflict while it is not graded, Invalid naming the
    field for an item not shown to them or an empty message, Conflict naming the rule for a second open request;
    Refused (429 with Retry-After) past the student's quota (settings.rate_limit_review_requests, every door)."""
    if submission.course_id != user.course_id or (access.is_student(user) and submission.student_id != user.id):
        raise NotFound(f"submission {submission.id} not found")
    if not access.is_student(user):
        raise Forbidden(f"only students may ask for a review; you are signed in as {user.role} {user.name}")
    quotas.take("review requests", user.id, settings.rate_limit_review_requests, field="review_requests",
                per="student")
    view = grade_view(session=session, submission=submission, user=user, now=now)
    if view.stored is None:
        raise Conflict(f"submission {submission.id} is {submission.status}, not graded: nothing to review yet")
    shown = [i["id"] for i in (view.report or {}).get("items", []) if i["id"] not in view.hidden]
    text, errors = _text(message, "message", MAX_MESSAGE, "say what you would like reviewed and why")
    if item_id not in shown:
        rule = (f"item {item_id} is withheld: {view.hidden[item_id]}" if item_id in view.hidden
                else f"must be an item of this grade shown to you ({', '.join(shown) or 'none yet'})")
        errors.insert(0, {"field": "item_id", "rule": rule})
    if errors:
        raise Invalid("invalid review request", errors)
    if _open_request(session, submission.id, item_id) is not None:
        raise _one_open(item_id)
    request = ReviewRequest(submission_id=submission.id, item_id=item_id, student_id=user.id, message=text,
                            created_at=now or utcnow())
    session.add(request)
    try:
        session.commit()
    except IntegrityError as exc:  # the open-request index: a second request raced this one
        session.rollback()
        raise _one_open(item_id) from exc
    return request


def _one_open(item_id: str) -> Conflict:
    rule = f"at most one open review request per item: item {item_id} already has one; wait for its answer"
    return Conflict(rule, [{"field": "item_id", "rule": rule}])


def _open_request(session: Session, submission_id: int, item_id: str) -> ReviewRequest | None:
    return session.scalar(select(ReviewRequest).where(ReviewRequest.submission_id == submission_id,
                                                      ReviewRequest.item_id == item_id,
                                                      ReviewRequest.answered_at.is_(None)))


# --- answering ----------------------------------------------------------------------------------------------------

def request_of(*, session: Session, user: User, request_id: int) -> ReviewRequest:
    """A review request of the caller's course (staff); NotFound for any other or for a student."""
    request = session.get(ReviewRequest, request_id) if 0 < request_id <= MAX_ID else None
    if request is None or request.submission.course_id != user.course_id or access.is_student(user):
        raise NotFound(f"review request {request_id} not found")
    return request


def answer(*, session: Session, request: ReviewRequest, user: User, text: str, score: float | None = None,
           now: datetime | None = None) -> ReviewRequest:
    """An instructor answers an open request (commits), with an override of the item when `score` is given (the
    answer is then its comment). Forbidden for anyone but an instructor, Conflict when already answered, Invalid
    naming each field (an empty answer, a score outside the item's points); nothing is stored then. The override marks
    the changed score for the LMS gradebooks (set_override); an answer alone changes no score."""
    require_instructor(user, action="answer a review request")
    if request.answered_at is not None:
        raise Conflict(f"review request {request.id} was answered by {request.answered_by.name} already")
    body, errors = _text(text, "answer", max(MAX_MESSAGE, MAX_COMMENT), "the student reads it on their report")
    if errors:
        raise Invalid("invalid answer", errors)
    now = now or utcnow()
    if score is not None:
        request.override = set_override(session=session, submission=request.submission, user=user,
                                        item_id=request.item_id, score=score, comment=body, now=now, commit=False)
    request.answer, request.answered_by_id, request.answered_by, request.answered_at = body, user.id, user, now
    session.commit()
    return request


# --- lists --------------------------------------------------------------------------------------------------------

def course_requests(*, session: Session, course_id: int, state: str = "open") -> list[ReviewRequest]:
    """The course's requests: open ones oldest first (the queue), answered ones newest first, or all by id."""
    if state not in STATES:
        raise Invalid("invalid state", [{"field": "state", "rule": f"must be one of {', '.join(STATES)}"}])
    query = select(ReviewRequest).join(Submission, ReviewRequest.submission_id == Submission.id).where(
        Submission.course_id == course_id)
    if state == "open":
        query = query.where(ReviewRequest.answered_at.is_(None)).order_by(ReviewRequest.created_at, ReviewRequest.id)
    elif state == "answered":
        query = query.where(ReviewRequest.answered_at.is_not(None)).order_by(ReviewRequest.answered_at.desc(),
                                                                             ReviewRequest.id.desc())
    else:
        query = query.order_by(ReviewRequest.id)
    return list(session.scalars(query))


def submission_requests(*, session: Session, submission: Submission, user: User,
                        hidden: dict[str, str] | None = None) -> list[ReviewRequest]:
    """A submission's requests as `user` may see them, oldest first: staff all; its student those about items shown
    to them now (`hidden`: the withheld items, from grader.services.submissions.visibility)."""
    rows = list(session.scalars(select(ReviewRequest).where(ReviewRequest.submission_id == submission.id)
                                .order_by(ReviewRequest.id)))
    if access.is_student(user):
        hidden = hidden if hidden is not None else grade_view(session=session, submission=submission, user=user,
                                                              report=False).hidden
        rows = [r for r in rows if r.item_id not in hidden]
    return rows
