"""Rubrics as data: one reviewed YAML file per lesson version, loaded into an immutable, hashable Rubric.

Governance lives here too (pure functions, no storage): a version that any grade used is immutable, a changed
tolerance needs a new version with its own review record, and a regrade is previewed per student before commit.
"""

from __future__ import annotations

import datetime as dt
import hashlib
import json
import re
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Literal

import yaml
from pydantic import BaseModel, ConfigDict, Field, model_validator
from pydantic_core import PydanticCustomError

if TYPE_CHECKING:  # scoring imports this module; the name is needed for annotations only
    from .scoring import GradeReport

LESSONS_DIR = Path(__file__).parent / "lessons"
VERSION_PATTERN = r"^[0-9]+(\.[0-9]+)*$"

ItemKind = Literal["computed", "measured", "conceptual", "config"]
ConfigRole = Literal["N1", "N2", "N3", "N4", "table_exercise", "extension"]


class RubricModel(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, strict=True)


class ReviewRecord(RubricModel):
    """Who reviewed what, and when; a new version must carry its own."""

    reviewer: Annotated[str, Field(min_length=1, max_length=128)]
    review_date: dt.date
    notes: str = ""


class Tolerance(RubricModel):
    """An accepted numerical range, justified before any result was seen; never widened to make a check pass."""

    value: Annotated[float, Field(ge=0.0)]
    unit: Annotated[str, Field(min_length=1, max_length=16)]
    rationale: Annotated[str, Field(min_length=20)]
    reviewer: Annotated[str, Field(min_length=1, max_length=128)]
    review_date: dt.date


class ConfigRule(RubricModel):
    """The one-factor rule of one submitted config: compared field by field with its declared baseline.

    `baseline` names another role (the student's own config of that role when submitted, else the lesson case of
    that name) or a lesson case; only the dotted field paths in `may_change` may differ from it.
    """

    baseline: str
    may_change: list[str]
    description: str


class Item(RubricModel):
    """One graded question: what it asks, what it is worth, how it is decided and under which tolerances."""

    id: Annotated[str, Field(pattern=r"^[A-Z][0-9]+$")]
    part: Literal["A", "B", "checkpoint", "hands_on", "extension"]
    question: Annotated[str, Field(min_length=5)]
    points: Annotated[float, Field(gt=0.0, le=100.0)]
    kind: ItemKind
    check: Annotated[str, Field(pattern=r"^[a-z][a-z0-9_]*$")]
    tolerances: list[str] = []
    # Config roles whose submitted spec this item reads: a one-factor violation there decides the item.
    roles: list[ConfigRole] = []


class Rubric(RubricModel):
    """A lesson's rubric at one version; content_hash identifies its exact content for grades and audits."""

    lesson: Annotated[str, Field(pattern=r"^L[0-9]{2}$")]
    version: Annotated[str, Field(pattern=VERSION_PATTERN)]
    engine_version: str
    review: ReviewRecord
    tolerances: dict[str, Tolerance]
    configs: dict[ConfigRole, ConfigRule]
    items: Annotated[list[Item], Field(min_length=1)]

    @model_validator(mode="after")
    def _consistent(self) -> "Rubric":
        ids = [item.id for item in self.items]
        dupes = sorted({i for i in ids if ids.count(i) > 1})
        if dupes:
            raise PydanticCustomError("duplicate_items", "items: duplicate item ids {ids}", {"ids": dupes})
        for n, item in enumerate(self.items):
            unknown = [t for t in item.tolerances if t not in self.tolerances]
            if unknown:
                raise PydanticCustomError(
                    "unknown_tolerance", "items.{n}.tolerances: {id} names unknown tolerances {t}",
                    {"n": n, "id": item.id, "t": unknown},
                )
        return self

    @property
    def content_hash(self) -> str:
        return hashlib.sha256(canonical_json(self).encode()).hexdigest()

    @property
    def max_total(self) -> float:
        return sum(item.points for item in self.items)

    def item(self, item_id: str) -> Item:
        return next(item for item in self.items if item.id == item_id)


def canonical_json(rubric: Rubric) -> str:
    """Sorted keys, no whitespace: the same content always hashes the same, whatever the file's layout."""
    return json.dumps(rubric.model_dump(mode="json"), sort_keys=True, separators=(",", ":"))


def parse_rubric(data: Mapping) -> Rubric:
    """A rubric from JSON-like data (a lesson file or a stored version); dates may be ISO strings."""
    return Rubric.model_validate_json(json.dumps(data, default=str))


def _version_key(version: str) -> tuple[int, ...]:
    return tuple(int(part) for part in version.split("."))


def rubric_versions(lesson: str = "L03") -> list[str]:
    """Versions shipped for a lesson, oldest first (files named LESSON-vVERSION.yaml)."""
    pattern = re.compile(rf"^{re.escape(lesson)}-v([0-9.]+)\.yaml$")
    found = [m.group(1) for p in LESSONS_DIR.glob("*.yaml") if (m := pattern.match(p.name))]
    return sorted(found, key=_version_key)


def load_rubric(lesson: str = "L03", version: str | None = None) -> Rubric:
    """The rubric of a lesson at `version`, or its latest version; the file's own lesson/version must agree."""
    versions = rubric_versions(lesson)
    if not versions:
        raise LookupError(f"no rubric files for lesson {lesson!r} in {LESSONS_DIR}")
    version = version or versions[-1]
    if version not in versions:
        raise LookupError(f"lesson {lesson} has no rubric version {version!r}; known: {', '.join(versions)}")
    rubric = parse_rubric(yaml.safe_load((LESSONS_DIR / f"{lesson}-v{version}.yaml").read_text()))
    if (rubric.lesson, rubric.version) != (lesson, version):
        raise ValueError(f"{lesson}-v{version}.yaml declares lesson {rubric.lesson} version {rubric.version}")
    return rubric


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
    earlier = [r for r in same_lesson if _version_key(r.version) < _version_key(new.version)]
    if not earlier:
        return new
    previous = max(earlier, key=lambda r: _version_key(r.version))
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


class RegradePreview(BaseModel):
    """What a regrade would change, per student, before anything is committed (old grades are always kept)."""

    rows: list[RegradeRow]

    @property
    def changed(self) -> list[RegradeRow]:
        return [row for row in self.rows if row.changed_items or row.old_score != row.new_score]


def regrade_preview(old: Mapping[str, "GradeReport"], new: Mapping[str, "GradeReport"]) -> RegradePreview:  # noqa: F821
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
    return RegradePreview(rows=rows)
