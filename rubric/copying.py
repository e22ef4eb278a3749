"""Copying made visible (issue 34 item 5, pure part): where a sheet fits another variant's expected answers better
than its own. Evidence for the instructor, never a grade: nothing here changes a score.

The caller grades the one sheet under each variant of the pool on that variant's stored runs
(`grade_sheet(sheet, runs_of_v, rubric, v)`), and compares with the grade under the student's own variant.
"""

from __future__ import annotations

from collections.abc import Mapping

from pydantic import BaseModel

from .scoring import GradeReport


class CopyEvidence(BaseModel):
    """Items the sheet gets right only on another variant: each with what the student's own variant expected and what
    that other variant expects (which is what the sheet answered)."""

    variant: str
    items: list[str]
    own_expected: dict[str, str]
    other_expected: dict[str, str]

    def describe(self) -> str:
        shown = "; ".join(f"{i}: own {self.own_expected[i]}, {self.variant} {self.other_expected[i]}" for i in self.items)
        return f"answers fit variant {self.variant} rather than the student's own on {len(self.items)} items ({shown})"


def copy_evidence(own: GradeReport, others: Mapping[str, GradeReport], *, min_items: int = 2) -> list[CopyEvidence]:
    """Per other variant: the items credited there but not on the student's own variant, where the two variants
    expect different answers (an item both expect alike proves nothing). Listed only from `min_items` such items,
    most items first; one coincidence is not evidence."""
    mine = {i.id: i for i in own.items}
    found = []
    for variant, report in others.items():
        if variant == own.variant:
            continue
        items = [i.id for i in report.items
                 if i.id in mine and i.verdict == "credit" and mine[i.id].verdict == "no_credit"
                 and i.expected != mine[i.id].expected]
        if len(items) >= min_items:
            found.append(CopyEvidence(variant=variant, items=items,
                                      own_expected={i: mine[i].expected for i in items},
                                      other_expected={i.id: i.expected for i in report.items if i.id in items}))
    return sorted(found, key=lambda e: (-len(e.items), e.variant))
