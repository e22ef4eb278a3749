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
    # How many measured items the two variants expect differently: the only ones that can tell them apart (issue 47).
    # 0 when unknown (evidence stored before it was counted).
    differing: int = 0

    def describe(self) -> str:
        shown = "; ".join(f"{i}: own {self.own_expected[i]}, {self.variant} {self.other_expected[i]}" for i in self.items)
        of = f" of the {self.differing} where the two variants differ" if self.differing else ""
        return (f"answers fit variant {self.variant} rather than the student's own on {len(self.items)} items{of} "
                f"({shown})")


def differing_items(own: GradeReport, other: GradeReport) -> list[str]:
    """The items measured on both variants (graded, not 'not_measured') whose expected answers differ: the only ones
    on which a sheet can fit one variant and not the other."""
    mine = {i.id: i for i in own.items}
    return [i.id for i in other.items if i.id in mine and i.expected != mine[i.id].expected
            and "not_measured" not in (i.verdict, mine[i.id].verdict)]


def indistinct_variants(own: GradeReport, others: Mapping[str, GradeReport]) -> list[str]:
    """The other variants no measured item tells apart from the student's own (they expect alike everywhere): copying
    between them cannot be seen, and the instructor is told so rather than shown no evidence."""
    return sorted(v for v, report in others.items() if v != own.variant and not differing_items(own, report))


def indistinct_pairs(reports: Mapping[str, GradeReport]) -> list[tuple[str, str]]:
    """Of variants each graded on its own runs ({variant: report}, in the pool's order), the pairs that no measured
    item tells apart: they expect alike on every item measured on both, so a sheet copied between the two fits both
    and no evidence can show it (issue 47). The instructor is told, rather than shown no evidence."""
    names = list(reports)
    return [(a, b) for i, a in enumerate(names) for b in names[i + 1:] if not differing_items(reports[a], reports[b])]


def copy_evidence(own: GradeReport, others: Mapping[str, GradeReport], *, min_items: int = 2) -> list[CopyEvidence]:
    """Per other variant: the items credited there but not on the student's own variant, where the two variants
    expect different answers (an item both expect alike proves nothing). Listed from `min_items` such items, or, for
    two variants that differ on fewer items than that (they share most answers, issue 47), when the sheet fits the
    other variant on every item where they differ; most items first. One coincidence among many is not evidence."""
    mine = {i.id: i for i in own.items}
    found = []
    for variant, report in others.items():
        if variant == own.variant:
            continue
        differing = differing_items(own, report)
        items = [i.id for i in report.items
                 if i.id in differing and i.verdict == "credit" and mine[i.id].verdict == "no_credit"]
        if len(items) >= min_items or (items and len(items) == len(differing) < min_items):
            found.append(CopyEvidence(variant=variant, items=items,
                                      own_expected={i: mine[i].expected for i in items},
                                      other_expected={i.id: i.expected for i in report.items if i.id in items},
                                      differing=len(differing)))
    return sorted(found, key=lambda e: (-len(e.items), e.variant))
