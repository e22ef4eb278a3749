"""The one rule by which an instructor's override reaches a score: a measured report with the submission's current
overrides applied. It lives in the core because grading (grader.core.grading.store_grade) applies it to every grade it
stores, so a submission graded again (a re-sent case run) keeps its overrides; grader.services.submissions.overrides writes them.

An overridden item keeps what was measured: its `verdict`, `measured_score` and `measured_max_score` beside the
`override` {score, comment, by, at}; its `score` is the override and it counts its full points (even an inconclusive
one, which the measurement alone left uncounted).
"""

from __future__ import annotations

from collections.abc import Iterable

from sqlalchemy import select
from sqlalchemy.orm import Session

from grader.core.models import Override

OVERRIDE_KEYS = ("measured_score", "measured_max_score", "override")


def measured_item(item: dict) -> dict:
    """An item as the rubric scored it: any override taken off, its measured score and max back in place."""
    if "override" not in item:
        return item
    bare = {k: v for k, v in item.items() if k not in OVERRIDE_KEYS}
    return bare | {"score": item["measured_score"], "max_score": item["measured_max_score"]}


def overridden_item(item: dict, override: Override) -> dict:
    """The measured item with `override` applied: the override's score (at most the item's points, which a newer
    rubric version may have lowered) counting the item's full points, the measurement kept beside it."""
    item = measured_item(item)
    return item | {"measured_score": item["score"], "measured_max_score": item["max_score"],
                   "score": min(override.score, item["points"]), "max_score": item["points"],
                   "override": {"score": min(override.score, item["points"]), "comment": override.comment,
                                "by": override.by.name, "at": f"{override.at.isoformat()}+00:00"}}


def overridden_report(report: dict, overrides: Iterable[Override]) -> dict:
    """`report` (a stored grade's, overridden or not) with exactly `overrides` applied, totals counted again.
    An override of an item the report does not hold (a newer rubric version dropped it) is left out."""
    by_item = {o.item_id: o for o in overrides}
    items = [overridden_item(i, by_item[i["id"]]) if i["id"] in by_item else measured_item(i)
             for i in report.get("items", [])]
    return {**report, "items": items, "total": round(sum(i["score"] for i in items), 6),
            "max_total": round(sum(i["max_score"] for i in items), 6)}


def current_overrides(session: Session, submission_id: int) -> list[Override]:
    """The overrides in force on a submission (one per item at most), by item id."""
    return list(session.scalars(select(Override).where(Override.submission_id == submission_id,
                                                       Override.superseded_at.is_(None)).order_by(Override.item_id)))
