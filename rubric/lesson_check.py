"""Whether a lesson's declaration and reviewed files can be used by a course (`grader lesson check`, issue 45 item 6):
every problem names the file, the field and the rule, so that a lesson author can fix it without reading this code.

What is checked, without running anything (the lab check's run on the CPU is the CLI's: grader/cli/lesson.py):
  declaration   a title in every language, English among them, case kinds and check cases that exist
  rubrics       every rubric version parses (schema, tolerances reviewed: value, unit, rationale, reviewer, date),
                declares this lesson and its own version, and every item of every gradable version names a scoring
                rule the lesson has
  audit, variant spaces
                every file parses and declares this lesson and its own version
  texts         for each language but English, the texts file exists and translates every item's question and every
                config rule of every rubric version
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import yaml
from pydantic import ValidationError

from .discrepancy import AuditTolerances
from .lesson import SOURCE_LANGUAGE, Lesson
from .rubrics import Rubric, parse_rubric
from .variants.space import parse_variant_space


@dataclass(frozen=True)
class Problem:
    """One thing wrong with a lesson: where (a file of its folder, or its declaration), which field, which rule."""

    where: str
    field: str
    rule: str

    def __str__(self) -> str:
        return f"{self.where}: {self.field}: {self.rule}"


def check_lesson(lesson: Lesson) -> list[Problem]:
    """Every problem of `lesson` (module docstring); none: a course may use it."""
    problems = _declaration(lesson)
    rubrics = {}
    for version, path in lesson.rubric_files().items():
        book, found = _parsed(path, parse_rubric, lesson.name, version)
        problems += found
        if book is not None:
            rubrics[version] = book
            if version not in lesson.archived_versions:
                problems += _rules(lesson, path, book)
    if not lesson.rubric_files():
        problems.append(Problem(str(lesson.files), f"{lesson.name}-v1.yaml", "a lesson needs at least one rubric "
                                                                             "version file"))
    for path in lesson.audit_files().values():
        problems += _parsed(path, lambda d: AuditTolerances.model_validate_json(json.dumps(d, default=str)),
                            lesson.name, _version_of(path))[1]
    for path in lesson.variant_files().values():
        problems += _parsed(path, parse_variant_space, lesson.name, _version_of(path))[1]
    for language in lesson.languages:
        if language != SOURCE_LANGUAGE:
            problems += _texts(lesson, language, rubrics)
    return problems


def _declaration(lesson: Lesson) -> list[Problem]:
    where, problems = f"the declaration of {lesson.name} ({lesson.origin or 'not installed'})", []
    if SOURCE_LANGUAGE not in lesson.languages:
        problems.append(Problem(where, "languages", f"must include {SOURCE_LANGUAGE!r}, the language every text is "
                                                    "written in"))
    for language in lesson.languages:
        if not (lesson.titles.get(language) or "").strip():
            problems.append(Problem(where, f"titles.{language}", "a title in every language the lesson teaches in"))
    kinds = {getattr(spec, "kind", None) for spec in lesson.cases.values()}
    unknown = sorted(str(k) for k in kinds - set(lesson.case_kinds))
    if unknown:
        problems.append(Problem(where, "cases", f"case kinds {unknown} are not among case_kinds "
                                                f"{sorted(lesson.case_kinds)}"))
    missing = [name for name in lesson.check_cases if name not in lesson.cases]
    if missing:
        problems.append(Problem(where, "check_cases", f"{missing} are not cases of the lesson"))
    return problems


def _version_of(path: Path) -> str:
    return path.stem.rsplit("-v", 1)[1]


def _parsed(path: Path, parse, name: str, version: str):
    """(the parsed file or None, its problems): schema errors by field, and a lesson or version other than its
    name's."""
    try:
        data = yaml.safe_load(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, yaml.YAMLError) as exc:
        return None, [Problem(path.name, "(file)", f"not readable YAML: {str(exc).splitlines()[0]}")]
    try:
        parsed = parse(data if isinstance(data, dict) else {})
    except ValidationError as exc:
        return None, [Problem(path.name, ".".join(str(p) for p in error["loc"]) or "(file)", error["msg"])
                      for error in exc.errors()]
    problems = []
    if parsed.lesson != name:
        problems.append(Problem(path.name, "lesson", f"declares lesson {parsed.lesson!r}, but the file belongs to "
                                                     f"{name}"))
    if parsed.version != version:
        problems.append(Problem(path.name, "version", f"declares version {parsed.version!r}, but the file's name "
                                                       f"says {version!r}"))
    return parsed, problems


def _rules(lesson: Lesson, path: Path, book: Rubric) -> list[Problem]:
    return [Problem(path.name, f"items.{n}.check", f"item {item.id} names scoring rule {item.check!r}, which "
                                                   f"{lesson.name} does not have (it has {len(lesson.scoring_rules)}: "
                                                   "every item needs one)")
            for n, item in enumerate(book.items) if item.check not in lesson.scoring_rules]


def _texts(lesson: Lesson, language: str, rubrics: dict[str, Rubric]) -> list[Problem]:
    path = lesson.text_file(language)
    if not path.is_file():
        return [Problem(path.name, "(file)", f"the lesson teaches in {language!r} but has no texts file for it")]
    try:
        data = yaml.safe_load(path.read_text(encoding="utf-8")) or {}
    except (OSError, UnicodeDecodeError, yaml.YAMLError) as exc:
        return [Problem(path.name, "(file)", f"not readable YAML: {str(exc).splitlines()[0]}")]
    problems = []
    for section, texts in (("questions", lambda b: [(f"item {i.id}", i.question) for i in b.items]),
                           ("configs", lambda b: [(f"config {role}", r.description) for role, r in b.configs.items()])):
        table = data.get(section) or {}
        seen = set()
        for version, book in rubrics.items():
            for what, english in texts(book):
                if english in seen:
                    continue
                seen.add(english)
                if not str(table.get(english) or "").strip():
                    problems.append(Problem(path.name, f"{section}.{english!r}", f"{what} of {lesson.name}-v{version}"
                                                                                f".yaml has no {language} text"))
    # What the declaration itself titles: its report's part headings and its charts
    for section, declared in (("part_titles", [(f"part {part}'s heading", title)
                                               for part, title in lesson.part_titles.items()]),
                              ("charts", [(f"chart {chart.id}'s title", chart.title) for chart in lesson.charts])):
        table = data.get(section) or {}
        problems += [Problem(path.name, f"{section}.{english!r}", f"{what} in {lesson.name}'s declaration has no "
                                                                  f"{language} text")
                     for what, english in declared if not str(table.get(english) or "").strip()]
    return problems


__all__ = ["Problem", "check_lesson"]
