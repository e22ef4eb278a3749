"""Conditional reads of a graded, complete report: an ETag built from the state the answer is made of, 304 to a
matching If-None-Match, and an in-process cache of the rendered bodies keyed by that same validator.

Why a validator and not a time: pages poll (the report page refreshes, the progress page asks again) and each read
rebuilt the whole report. A complete report changes only when one of its inputs does, and each input is named here:
the current grade's id (a regrade or an override stores a new grade), its completion, the submission's state and
runs, the reader (user id, role and name: never one user's answer to another), which items are withheld from that
reader and why, and which items of the lesson are withheld from the submission's student in any assignment (their
runs are withheld here: a release or a due date passing changes either, so a 304 can never hide a newly shown item
or run), the review
requests and their answers, the attempt's standing, the course's name and time zone, and for the page its language
and address.

Only a complete report gets one: while a submission is measured, graded or its lab check is being added, answers
carry no ETag and are built each time.
"""

from __future__ import annotations

import hashlib
import json
import threading
from collections import OrderedDict
from collections.abc import Callable
from datetime import datetime

from fastapi import Request, Response
from sqlalchemy import select
from sqlalchemy.orm import Session

from grader.core.states import SubmissionState
from grader.core.models import CaseRun, ReviewRequest, Submission, User
from grader.core.models import utcnow
from grader.services.submissions.visibility import GradeView, next_shown_at
from grader.web import fresh
from grader.web.fresh import CACHE_CONTROL, SHAPE, matches_header

# Rendered answers kept per API process (a report page is tens to a few hundred kB): bounded by count, not bytes.
CACHE_ENTRIES = 256


def complete(submission: Submission, view: GradeView) -> bool:
    """Whether the report is final until a person changes something: graded, its lab check added, none in flight."""
    return (submission.status == SubmissionState.GRADED and view.stored is not None
            and view.stored.completed_at is not None)


def report_state(session: Session, submission: Submission, user: User, view: GradeView) -> list:
    """What every answer about a complete report is made of, as JSON-ready values (see the module's docstring)."""
    reviews = session.execute(select(ReviewRequest.id, ReviewRequest.answered_at, ReviewRequest.override_id)
                              .where(ReviewRequest.submission_id == submission.id)
                              .order_by(ReviewRequest.id)).all()
    # the runs' states only: loading the rows would decode every run's spec, provenance and metrics for a 304
    runs = session.execute(select(CaseRun.id, CaseRun.status, CaseRun.delivery)
                           .where(CaseRun.submission_id == submission.id).order_by(CaseRun.id)).all()
    course = user.course
    return [SHAPE, user.id, str(user.role), user.name, user.course_id, course.name if course else None,
            course.timezone if course else None, submission.id, submission.student.name, str(submission.status),
            str(submission.updated_at), submission.assignment_id,
            [tuple(map(str, r)) for r in runs],
            view.stored.id, str(view.stored.completed_at), str(view.stored.superseded_at),
            sorted(view.hidden.items()), sorted(view.lesson_hidden.items()),
            [(r.id, str(r.answered_at), r.override_id) for r in reviews]]


def shown_until(session: Session, submission: Submission, user: User, view: GradeView) -> datetime | None:
    """The next instant at which time alone shows `user` an item withheld now (a due date passing), or None: the
    validator store must not confirm this answer from that instant on."""
    if not view.hidden and not view.lesson_hidden:
        return None
    return next_shown_at(session=session, submission=submission, user=user, now=utcnow())


def etag_of(kind: str, state: list, *extra) -> str:
    """A strong ETag for one kind of answer (page, JSON, results) over its state and anything else it varies by."""
    blob = json.dumps([kind, state, *extra], default=str, separators=(",", ":"))
    return '"' + hashlib.sha256(blob.encode()).hexdigest()[:32] + '"'


def matches(request: Request, etag: str) -> bool:
    """Whether the request's If-None-Match names `etag` (weak comparison, as RFC 9110 asks for If-None-Match)."""
    return matches_header(request.headers.get("if-none-match"), etag)


def not_modified(etag: str) -> Response:
    return Response(status_code=304, headers={"ETag": etag, "Cache-Control": CACHE_CONTROL})


class BodyCache:
    """Rendered 200 answers by validator, least recently used out first. The key holds the reader's id, so an answer
    is only ever served again to the reader it was built for; thread-safe (sync routes run in a thread pool)."""

    def __init__(self, entries: int = CACHE_ENTRIES):
        self.entries = entries
        self._answers: OrderedDict[str, tuple[bytes, str | None, dict]] = OrderedDict()
        self._lock = threading.Lock()
        self.hits = self.misses = 0

    def get(self, key: str) -> Response | None:
        with self._lock:
            kept = self._answers.get(key)
            if kept is None:
                self.misses += 1
                return None
            self._answers.move_to_end(key)
            self.hits += 1
        body, media_type, headers = kept
        return Response(body, media_type=media_type, headers=headers)

    def put(self, key: str, response: Response) -> None:
        """Keeps a 200 answer's body, type and own headers (not its cookies: none of these answers sets one)."""
        if response.status_code != 200 or "set-cookie" in response.headers:
            return
        headers = {k: v for k, v in response.headers.items() if k not in ("content-length", "content-type")}
        with self._lock:
            self._answers[key] = (bytes(response.body), response.media_type, headers)
            self._answers.move_to_end(key)
            while len(self._answers) > self.entries:
                self._answers.popitem(last=False)

    def clear(self) -> None:
        with self._lock:
            self._answers.clear()
            self.hits = self.misses = 0


BODIES = BodyCache()


def conditional(request: Request, etag: str | None, build: Callable[[], Response], *,
                cache_key: str | None = None, until: datetime | None = None) -> Response:
    """304 where the request already holds `etag`; otherwise the answer `build` makes, marked with `etag`. With a
    `cache_key` (the kind of answer; the ETag is appended), a 200 answer is built once per validator and process.
    `etag` None (an incomplete report): built each time, no ETag. The validator is kept for grader.web.fresh's 304
    from memory until `until` at the latest (when time alone changes the answer: `shown_until`)."""
    if etag is None:
        return build()
    fresh.remember(request, etag, until)
    if matches(request, etag):
        return not_modified(etag)
    key = f"{cache_key}:{etag}" if cache_key else None
    response = BODIES.get(key) if key else None
    if response is None:
        response = build()
        if key:
            BODIES.put(key, response)
    if response.status_code == 200:
        response.headers["ETag"] = etag
        response.headers["Cache-Control"] = CACHE_CONTROL
    return response
