"""A person's judgement on a grade: an instructor's override of one item's score, and a student's review request of
one item with an instructor's answer (grader.services.submissions.overrides, grader.services.submissions.review_requests)."""

from __future__ import annotations

from typing import Literal

from fastapi import APIRouter, status
from pydantic import Field

from grader.web.deps import CurrentUser, InstructorUser, RowId, SessionDep, StaffCourse, StaffUser, SubmissionDep
from grader.api.responses import errors
from grader.core.schemas import Strict
from grader.services.submissions import overrides, review_requests
from grader.services.submissions.overrides import MAX_COMMENT, OverridePublic
from grader.services.submissions.review_requests import MAX_MESSAGE, ReviewRequestPublic

router = APIRouter(tags=["reviews"], responses=errors(401, 404, 422))


class OverrideCreate(Strict):
    """One item's score set by an instructor, with the comment the student reads beside the measured verdict."""

    item_id: str = Field(min_length=1, max_length=16, description="A rubric item of the submission's grade, e.g. H1")
    score: float = Field(description="Points, from 0 to the item's points")
    comment: str = Field(max_length=MAX_COMMENT, description="Why (required; the student reads it)")


class ReviewRequestCreate(Strict):
    """A student's request that an instructor review one item shown to them."""

    item_id: str = Field(min_length=1, max_length=16)
    message: str = Field(max_length=MAX_MESSAGE, description="What to review and why (required)")


class ReviewAnswer(Strict):
    """An instructor's answer; with `score`, the item is overridden with the answer as its comment."""

    answer: str = Field(max_length=max(MAX_MESSAGE, MAX_COMMENT))
    score: float | None = Field(None, description="A new score for the item (0 to its points), or none")


@router.post("/submissions/{submission_id}/overrides", status_code=status.HTTP_201_CREATED,
             response_model=OverridePublic, responses=errors(403, 409, _409="Not graded yet, or its lab check is "
                                                                            "still being evaluated"))
def create_override(body: OverrideCreate, submission: SubmissionDep, session: SessionDep, user: InstructorUser):
    """Set one item's score on a submission (instructors of its course), with a required comment; the measured
    verdict stays beside it and the previous grade is kept in the history."""
    made = overrides.set_override(session=session, submission=submission, user=user, item_id=body.item_id,
                                  score=body.score, comment=body.comment)
    return overrides.public(session, made)


@router.get("/submissions/{submission_id}/overrides", response_model=list[OverridePublic], responses=errors(403))
def list_overrides(submission: SubmissionDep, session: SessionDep, user: StaffUser):
    """Every override of the submission, oldest first, superseded ones kept (staff of its course)."""
    return [overrides.public(session, o) for o in overrides.override_history(session, submission.id)]


@router.post("/submissions/{submission_id}/review-requests", status_code=status.HTTP_201_CREATED,
             response_model=ReviewRequestPublic,
             responses=errors(403, 409, 429, _409="Not graded yet, or this item already has an open request",
                              _429="More review requests than RATE_LIMIT_REVIEW_REQUESTS allows (Retry-After says when)"))
def create_review_request(body: ReviewRequestCreate, submission: SubmissionDep, session: SessionDep,
                          user: CurrentUser):
    """Ask for a review of one item of your own graded submission shown to you (at most one open per item)."""
    return review_requests.public(review_requests.ask(session=session, submission=submission, user=user,
                                                      item_id=body.item_id, message=body.message))


@router.get("/submissions/{submission_id}/review-requests", response_model=list[ReviewRequestPublic])
def list_submission_requests(submission: SubmissionDep, session: SessionDep, user: CurrentUser):
    """The submission's review requests, oldest first, with their answers (a student: those about items shown)."""
    return [review_requests.public(r) for r in
            review_requests.submission_requests(session=session, submission=submission, user=user)]


@router.get("/courses/{course}/review-requests", response_model=list[ReviewRequestPublic], responses=errors(403))
def list_course_requests(course: StaffCourse, session: SessionDep,
                         state: Literal["open", "answered", "all"] = "open"):
    """The course's review requests: open ones oldest first (the queue), answered ones newest first, or all."""
    return [review_requests.public(r) for r in
            review_requests.course_requests(session=session, course_id=course.id, state=state)]


@router.post("/review-requests/{request_id}/answer", response_model=ReviewRequestPublic,
             responses=errors(403, 409, _409="Already answered, or the override cannot be set now"))
def answer_request(request_id: RowId, body: ReviewAnswer, session: SessionDep, user: InstructorUser):
    """Answer an open review request (instructors of its course), overriding the item's score when `score` is
    given; the student reads the answer on their report."""
    request = review_requests.request_of(session=session, user=user, request_id=request_id)
    return review_requests.public(review_requests.answer(session=session, request=request, user=user,
                                                         text=body.answer, score=body.score))
