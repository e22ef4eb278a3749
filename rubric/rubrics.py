"""Rubrics as data: one reviewed YAML file per lesson version, loaded into an immutable, hashable Rubric.

What may change between versions, and how a regrade is previewed, is rubric.governance.
"""

from __future__ import annotations

import datetime as dt
import functools
import hashlib
import json
import re
from collections.abc import Mapping
from pathlib import Path
from typing import Annotated, Literal

import yaml
from pydantic import BaseModel, ConfigDict, Field, model_validator
from pydantic_core import PydanticCustomError

LESSONS_DIR = Path(__file__).parent / "lessons"
VERSION_PATTERN = r"^[0-9]+(\.[0-9]+)*$"

ItemKind = Literal["computed", "measured", "conceptual", "config"]
# A role of the sheet's configs (its lesson's sheet model names them: L03's N1-N4, table_exercise, extension);
# `grader lesson check` finds a rubric naming one its sheet does not have.
ConfigRole = Annotated[str, Field(pattern=r"^[A-Za-z][A-Za-z0-9_]*$", max_length=32)]


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
    # Read by v1 only (archived). Since v2 the runs an item's check actually reads decide which config faults void it.
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


def version_key(version: str) -> tuple[int, ...]:
    return tuple(int(part) for part in version.split("."))


def lesson_folder(lesson: str) -> Path | None:
    """The folder of a lesson's reviewed files (rubric versions, audit tolerances, variant spaces, texts per
    language), as its declaration says (rubric.lesson, found by entry point); None for a lesson not installed."""
    from .lesson import LessonNotFound, lesson as declared  # here, not at the top: a declaration imports this module

    try:
        return declared(lesson).files
    except LessonNotFound:
        return None


def rubric_versions(lesson: str = "L03") -> list[str]:
    """Versions shipped for a lesson, oldest first (files named LESSON-vVERSION.yaml in its folder)."""
    folder = lesson_folder(lesson)
    if folder is None:
        return []
    pattern = re.compile(rf"^{re.escape(lesson)}-v([0-9.]+)\.yaml$")
    found = [m.group(1) for p in folder.glob("*.yaml") if (m := pattern.match(p.name))]
    return sorted(found, key=version_key)


@functools.lru_cache(maxsize=16)
def _parsed(text: str) -> Rubric:
    """A rubric file's text parsed once per process: the service records the shipped files before every grade
    (grader.core.rubrics.sync_shipped), and parsing two with PyYAML's pure-Python loader took ~0.1 s of each."""
    return parse_rubric(yaml.load(text, Loader=getattr(yaml, "CSafeLoader", yaml.SafeLoader)))


def _shipped(lesson: str, version: str | None) -> Rubric:
    """The parsed file of a lesson at `version` (or its latest), shared by every caller in this process: not to be
    changed; the file's own lesson/version must agree."""
    versions = rubric_versions(lesson)
    if not versions:
        raise LookupError(f"no rubric files for lesson {lesson!r} in {lesson_folder(lesson) or 'no installed lesson'}")
    version = version or versions[-1]
    if version not in versions:
        raise LookupError(f"lesson {lesson} has no rubric version {version!r}; known: {', '.join(versions)}")
    rubric = _parsed((lesson_folder(lesson) / f"{lesson}-v{version}.yaml").read_text())
    if (rubric.lesson, rubric.version) != (lesson, version):
        raise ValueError(f"{lesson}-v{version}.yaml declares lesson {rubric.lesson} version {rubric.version}")
    return rubric


def load_rubric(lesson: str = "L03", version: str | None = None) -> Rubric:
    """The rubric of a lesson at `version`, or its latest version; the file's own lesson/version must agree. A copy
    of its own for the caller."""
    return _shipped(lesson, version).model_copy(deep=True)


def shipped_hash(lesson: str, version: str) -> str:
    """The content hash of a shipped rubric file, without the deep copy load_rubric hands out (~7 ms on a busy host):
    grader.core.rubrics.sync_shipped compares it with its recorded row for every submission, grade and lab check."""
    return _shipped(lesson, version).content_hash
