"""Rubric governance, pure functions with no storage: a version that any grade used is immutable, a changed
tolerance needs a new version with its own review record, and a regrade is previewed per student before commit.
A lesson's variant space (rubric.variants) is governed by the same rules: publish_variant_space.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

from pydantic import BaseModel

from .rubrics import Rubric, version_key
from .scoring import GradeReport
from .variants.space import VariantSpace


class RubricGovernanceError(ValueError):
    """A rubric change that governance forbids (editing a used version, an unreviewed tolerance change)."""


def publish_version(new: Rubric, existing: Sequence[Rubric], used_versions: set[str]) -> Rubric:
    """Accept `new` as a publishable version of its lesson, or raise RubricGovernanceError saying why not.

    - A version id that any grade used is immutable: the same id with different content is refused.
    - Republishing identical content is a no-op; an unused draft may still be replaced.
    - A new version needs its own review record, and every tolerance whose value or unit differs from the latest
      earlier version needs a fresh review (reviewer or date differing from the old record, date not earlier).
    """
    same_lesson = [r for r in existing if r.lesson == new.lesson]
    prior = next((r for r in same_lesson if r.version == new.version), None)
    if prior is not None:
        if prior.content_hash == new.content_hash:
            return prior
        if new.version in used_versions:
            raise RubricGovernanceError(
                f"rubric {new.lesson} version {new.version} is used by existing grades and is immutable "
                f"(stored hash {prior.content_hash[:12]}, new {new.content_hash[:12]}); "
                f"changes: {', '.join(rubric_changes(prior, new)) or 'content'}; publish them as a new version"
            )
    earlier = [r for r in same_lesson if version_key(r.version) < version_key(new.version)]
    if not earlier:
        return new
    previous = max(earlier, key=lambda r: version_key(r.version))
    if new.review == previous.review:
        raise RubricGovernanceError(
            f"version {new.version} repeats the review record of version {previous.version}; a new version needs its own review"
        )
    for name, tol in new.tolerances.items():
        old = previous.tolerances.get(name)
        if old is None or (old.value, old.unit) == (tol.value, tol.unit):
            continue
        if (tol.reviewer, tol.review_date) == (old.reviewer, old.review_date) or tol.review_date < old.review_date:
            raise RubricGovernanceError(
                f"tolerances.{name}: changed {old.value} {old.unit} -> {tol.value} {tol.unit} without a new review "
                f"(reviewer and date still {old.reviewer}, {old.review_date})"
            )
    return new


def rubric_changes(old: Rubric, new: Rubric) -> list[str]:
    """Human-readable differences between two rubric versions (tolerances and item points first)."""
    changes = []
    for name in sorted(set(old.tolerances) | set(new.tolerances)):
        a, b = old.tolerances.get(name), new.tolerances.get(name)
        if a != b:
            describe = lambda t: f"{t.value} {t.unit}" if t else "absent"  # noqa: E731
            changes.append(f"tolerances.{name}: {describe(a)} -> {describe(b)}")
    old_items, new_items = {i.id: i for i in old.items}, {i.id: i for i in new.items}
    for item_id in sorted(set(old_items) | set(new_items)):
        if old_items.get(item_id) != new_items.get(item_id):
            changes.append(f"items.{item_id}")
    for field in ("engine_version", "review", "configs"):
        if getattr(old, field) != getattr(new, field):
            changes.append(field)
    return changes


def publish_variant_space(new: VariantSpace, existing: Sequence[VariantSpace], used_versions: set[str]) -> VariantSpace:
    """Accept `new` as a publishable variant space of its lesson, or raise RubricGovernanceError saying why not.

    The rules of publish_version: a version any pool used is immutable (identical content is a no-op, an unused draft
    may be replaced); a new version needs its own review record; every parameter or constraint whose content differs
    from the latest earlier version's needs a fresh review (reviewer or date differing, date not earlier)."""
    same_lesson = [s for s in existing if s.lesson == new.lesson]
    prior = next((s for s in same_lesson if s.version == new.version), None)
    if prior is not None:
        if prior.content_hash == new.content_hash:
            return prior
        if new.version in used_versions:
            raise RubricGovernanceError(
                f"variant space {new.lesson} version {new.version} is used by a variant pool and is immutable "
                f"(stored hash {prior.content_hash[:12]}, new {new.content_hash[:12]}); changes: "
                f"{', '.join(variant_space_changes(prior, new)) or 'content'}; publish them as a new version")
    earlier = [s for s in same_lesson if version_key(s.version) < version_key(new.version)]
    if not earlier:
        return new
    previous = max(earlier, key=lambda s: version_key(s.version))
    if new.review == previous.review:
        raise RubricGovernanceError(f"variant space version {new.version} repeats the review record of version "
                                    f"{previous.version}; a new version needs its own review")
    for section in ("parameters", "constraints"):
        for name, declared in getattr(new, section).items():
            old = getattr(previous, section).get(name)
            if old is None or _declared(old) == _declared(declared):
                continue
            if (declared.reviewer, declared.review_date) == (old.reviewer, old.review_date) or \
                    declared.review_date < old.review_date:
                raise RubricGovernanceError(
                    f"{section}.{name}: changed {_declared(old)} -> {_declared(declared)} without a new review "
                    f"(reviewer and date still {old.reviewer}, {old.review_date})")
    return new


def _declared(declared) -> dict:
    """What a parameter or constraint declares, without its review record (a rationale's wording is not a change)."""
    return declared.model_dump(mode="json", exclude={"rationale", "reviewer", "review_date"}, exclude_none=True)


def variant_space_changes(old: VariantSpace, new: VariantSpace) -> list[str]:
    """Human-readable differences between two variant space versions (what varies, then the constraints)."""
    changes = []
    for section in ("parameters", "constraints"):
        a, b = getattr(old, section), getattr(new, section)
        for name in sorted(set(a) | set(b)):
            if a.get(name) != b.get(name):
                show = lambda d: _declared(d) if d is not None else "absent"  # noqa: E731
                changes.append(f"{section}.{name}: {show(a.get(name))} -> {show(b.get(name))}")
    for field in ("grading_rubric", "engine_version", "review"):
        if getattr(old, field) != getattr(new, field):
            changes.append(field)
    return changes


class ItemChange(BaseModel):
    id: str
    old_score: float | None
    new_score: float | None
    old_verdict: str | None
    new_verdict: str | None


class RegradeRow(BaseModel):
    student: str
    old_version: str | None
    new_version: str | None
    old_score: float | None
    new_score: float | None
    old_max: float | None
    new_max: float | None
    changed_items: list[ItemChange]

    @property
    def delta(self) -> float | None:
        if self.old_score is None or self.new_score is None:
            return None
        return self.new_score - self.old_score


class ReportChanges(BaseModel):
    """What a regrade would change, per student, before anything is committed (old grades are always kept)."""

    rows: list[RegradeRow]

    @property
    def changed(self) -> list[RegradeRow]:
        return [row for row in self.rows if row.changed_items or row.old_score != row.new_score]


def report_changes(old: Mapping[str, GradeReport], new: Mapping[str, GradeReport]) -> ReportChanges:
    """Per student: old and new score and every item whose score or verdict differs (students on either side)."""
    rows = []
    for student in sorted(set(old) | set(new)):
        a, b = old.get(student), new.get(student)
        a_items = {i.id: i for i in a.items} if a else {}
        b_items = {i.id: i for i in b.items} if b else {}
        changed = []
        for item_id in list(a_items) + [i for i in b_items if i not in a_items]:
            x, y = a_items.get(item_id), b_items.get(item_id)
            if x is None or y is None or (x.score, x.verdict) != (y.score, y.verdict):
                changed.append(ItemChange(
                    id=item_id,
                    old_score=x.score if x else None, new_score=y.score if y else None,
                    old_verdict=x.verdict if x else None, new_verdict=y.verdict if y else None,
                ))
        rows.append(RegradeRow(
            student=student,
            old_version=a.rubric_version if a else None, new_version=b.rubric_version if b else None,
            old_score=a.total if a else None, new_score=b.total if b else None,
            old_max=a.max_total if a else None, new_max=b.max_total if b else None,
            changed_items=changed,
        ))
    return ReportChanges(rows=rows)
