"""Drafts: a student's unsent sheet for an assignment (or their free sheet), kept on the server as they type, within
the sheet's caps (grader.services.submissions.sheets) and the person's draft-save quota (settings.rate_limit_draft_saves)."""

from __future__ import annotations

from sqlalchemy import select
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from grader.core.models import Assignment, Draft, Submission, User, utcnow
from grader.services.identity import quotas
from grader.services.submissions import sheets
from grader.core.settings import settings


def _query(user: User, assignment: Assignment | None):
    aid = assignment.id if assignment is not None else None
    return select(Draft).where(Draft.user_id == user.id,
                               Draft.assignment_id.is_(None) if aid is None else Draft.assignment_id == aid)


def load(*, session: Session, user: User, assignment: Assignment | None) -> Draft | None:
    return session.scalar(_query(user, assignment))


def save(*, session: Session, user: User, assignment: Assignment | None, sheet: dict) -> Draft:
    """Store the sheet as the user's draft (replacing the one before); commits. Refused (429 with Retry-After) past
    the person's draft-save quota, Invalid naming the path for a sheet past the caps; nothing is stored then. Two
    saves racing to create it: the database keeps one row (unique per user and assignment) and the later save writes
    into it."""
    quotas.take("draft saves", user.id, settings.rate_limit_draft_saves, field="draft")
    sheets.check_size(sheet)
    draft = load(session=session, user=user, assignment=assignment)
    if draft is None:
        draft = Draft(user_id=user.id, assignment_id=assignment.id if assignment else None, sheet=sheet)
        session.add(draft)
        try:
            session.commit()
            return draft
        except IntegrityError:
            session.rollback()
            draft = load(session=session, user=user, assignment=assignment)
    draft.sheet, draft.updated_at = sheet, utcnow()
    session.commit()
    return draft


def last_submitted(*, session: Session, user: User, assignment: Assignment | None) -> Submission | None:
    """The user's latest submission to the assignment (to their free sheet: outside any assignment)."""
    query = select(Submission).where(Submission.student_id == user.id)
    query = query.where(Submission.assignment_id.is_(None) if assignment is None
                        else Submission.assignment_id == assignment.id)
    return session.scalar(query.order_by(Submission.id.desc()).limit(1))
