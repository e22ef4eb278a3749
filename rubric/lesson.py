"""What a lesson is to the service: one declaration per lesson (`Lesson`), found by entry point.

A course teaches many lessons, and the service grades any lesson that declares itself (issue 45, DESIGN.md "Lessons").
A lesson's package exposes one `Lesson` under the entry-point group ENTRY_POINTS (pyproject.toml:
`[project.entry-points."l03_grader.lessons"] L03 = "rubric.l03:LESSON"`), so a lesson can be its own installable
distribution. The declaration says everything a lesson owns:

  name, titles        "L03", and its title in every language the course teaches in (`languages`)
  files               the folder of its reviewed files: rubric versions (NAME-vV.yaml), audit tolerances
                      (NAME-audit-vV.yaml), variant spaces (NAME-lab-variants-vV.yaml) and the texts of each language
                      but English (NAME.LANG.yaml); their governance is rubric.governance's, as for every lesson
  case_kinds          {kind: its case spec model}: what a student's config may be
  scenes              the module that builds each case kind's Genesis scene and records its samples
                      (worker.scene_kit says what it provides; the runner hands it the initialised Genesis),
                      imported by name inside the case process alone
  warm_up_cases       the cases a warm case process runs first, one per scene structure
  figures             the module drawing its PNG figures (a grader check's report, a backend audit)
  cases               its baseline case table; check_cases the names its lab check runs
  scoring_rules       {rule name: scoring function}: every rubric item's `check` must name one
  grade_sheet, cases_to_run, evaluate_check, verdict_line
                      how a sheet is graded on measured runs, which runs a sheet needs, the lab check on measured
                      runs (`<NAME> CHECK: PASSED` and its conditions)
  runs_read           which of a submission's runs could tell an item's answer (withheld with the item)
  physics_key         what a case's runs measure, however sampled or labelled: runs of one key tell the same

Pure: this module imports nothing of the service; `lesson("L03")` imports the lesson's declaring module only.
Step 2 of issue 45: L03 is declared here and `grader lesson check` reads the declaration; the service's other layers
still call L03's modules directly, and move to the declaration in the next steps.
"""

from __future__ import annotations

import dataclasses
import functools
import importlib.util
import re
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from importlib import metadata
from pathlib import Path
from typing import Any

ENTRY_POINTS = "l03_grader.lessons"
NAME_PATTERN = r"^L[0-9]{2}$"
# A submission's run of a student's own config is named after its role in the sheet: "sheet.extension".
SHEET_CASE_PREFIX = "sheet."
# English is the language every text is written in; the others are translations beside the rubric (NAME.LANG.yaml).
SOURCE_LANGUAGE = "en"


@dataclass(frozen=True)
class SeriesChart:
    """One chart of a lesson's report, drawn in the reader's browser: one sampled series of every run of a case kind,
    overlaid against simulated time (grader/static/report_charts.js). Its caption gives each run's key numbers in
    words, from the run's stored metrics, so the chart has a text alternative."""

    id: str  # the chart's id on the report page ("drop-z")
    kind: str  # the case kind whose runs it overlays ("drop")
    series: str  # the sampled array drawn, one value per sample ("z")
    title: str  # in English; translated by the NAME.LANG.yaml section "charts"
    axis: str  # the y axis's label, with its unit ("z (m)")
    words: Callable[[Mapping[str, Any]], str]  # a run's stored metrics -> its key numbers in words
    # The metric that holds a run's first contact time, if any: "Zoom to the contact window" zooms to it
    first_contact: str = ""
    stepped: bool = False  # a count drawn as steps


@dataclass(frozen=True)
class Lesson:
    """One lesson's declaration (module docstring): its name and texts, its reviewed files, its cases, its scoring
    and its lab check."""

    name: str
    titles: Mapping[str, str]
    files: Path
    case_kinds: Mapping[str, type]
    scenes: str
    cases: Mapping[str, Any]
    check_cases: Sequence[str]
    scoring_rules: Mapping[str, Callable]
    grade_sheet: Callable
    cases_to_run: Callable
    evaluate_check: Callable
    verdict_line: Callable[..., str]
    # (item id, a submission's run names) -> the runs whose measurements could tell that item's answer: what is
    # withheld with the item, in every submission of the student (grader.services.submissions.visibility)
    runs_read: Callable[[str, Sequence[str]], list[str]]
    # (case kind, a stored spec) -> the physics it integrates however sampled, labelled or run (None: not a valid
    # spec): runs of one key measure the same, and are withheld together (grader.services.submissions.visibility)
    physics_key: Callable[[str, Mapping[str, Any]], str | None]
    languages: Sequence[str] = (SOURCE_LANGUAGE,)
    # Names in `cases` a warm case process runs before any real case, one per scene structure its cases use, so a
    # first submission builds no scene (worker.warm_process.warm_up)
    warm_up_cases: Sequence[str] = ()
    # The module drawing its figures as PNGs, imported by name where figures are drawn (worker.figures):
    # lab_figures(results, out_dir, *, cache) for a grader check's report, draw_comparison(a, b, comparison, folder)
    # for a backend audit. Empty: it draws none.
    figures: str = ""
    # Rubric versions kept readable for the grades stored under them but never used to grade again: their items may
    # name rules the lesson no longer has.
    archived_versions: Sequence[str] = ()
    # Its sheet: (data, part) -> the validated sheet (pydantic.ValidationError naming each bad item), part being
    # "checkpoints", "exercises" or "sheet". A sheet has `lesson`, `student`, `answers` (one field per item it answers)
    # and `configs` (`submitted()`: {role: spec} of the student's own configs).
    parse_sheet: Callable[[Any, str], Any] | None = None
    # (sheet, rubric, variant) -> {role: rubric.one_factor.ConfigFinding}: each submitted config compared with the
    # baseline its rubric rule declares (a config that breaks its rule is graded as such, never run).
    config_findings: Callable[..., Mapping[str, Any]] | None = None
    # The model of its whole sheet (parse_sheet's for the part "sheet"): its `answers` model has one field per item,
    # its `configs` model one per config role (the required ones are those the sheet form edits).
    sheet_model: type | None = None
    # variant -> the specs of the lesson's own runs every sheet is graded on (what a form's Check reads as stored)
    lesson_run_specs: Callable[[Any], Sequence[Any]] | None = None
    # The items of its concept checkpoints: a sheet answering only these needs no config of its own.
    checkpoint_ids: Sequence[str] = ()
    # Per case kind, where a case ran (worker.case_process): the arrays a valid result holds ({name: (shape or None
    # for a frame, dtype kind)}) and the metrics computed from them once; `metrics_models` {kind: model} reads stored
    # metrics back (each model has a `kind` field).
    expected_arrays: Callable[[Any], dict] | None = None
    case_metrics: Callable[[Any, Mapping], Any] | None = None
    metrics_models: Mapping[str, type] = field(default_factory=dict)
    # {rubric item part: its heading on a report} in English (translated by the NAME.LANG.yaml section "part_titles");
    # a part it leaves out is headed as the service heads it
    part_titles: Mapping[str, str] = field(default_factory=dict)
    # The charts of its report (SeriesChart), beyond the ones the service draws for L03's contact and friction runs
    charts: Sequence[SeriesChart] = ()
    origin: str = field(default="", compare=False)  # where the declaration was found (an entry point or a file)

    def title(self, language: str) -> str:
        """The lesson's title in `language`, else in English."""
        return self.titles.get(language) or self.titles[SOURCE_LANGUAGE]

    def rubric_files(self) -> dict[str, Path]:
        """{version: file} of its rubric versions, oldest first."""
        return _versioned(self.files, rf"^{re.escape(self.name)}-v([0-9.]+)\.yaml$")

    def audit_files(self) -> dict[str, Path]:
        return _versioned(self.files, rf"^{re.escape(self.name)}-audit-v([0-9.]+)\.yaml$")

    def variant_files(self) -> dict[str, Path]:
        return _versioned(self.files, rf"^{re.escape(self.name)}-lab-variants-v([0-9.]+)\.yaml$")

    def answers_model(self) -> type:
        """The model of a whole sheet's answers: one field per item, its answer's model."""
        return self.sheet_model.model_fields["answers"].annotation

    def configs_model(self) -> type:
        return self.sheet_model.model_fields["configs"].annotation

    def form_configs(self) -> tuple[str, ...]:
        """The config roles every whole sheet submits (the sheet form edits them; optional ones travel in YAML)."""
        return tuple(name for name, info in self.configs_model().model_fields.items() if info.is_required())

    def text_file(self, language: str) -> Path:
        """Where its texts in `language` (not English) live."""
        return self.files / f"{self.name}.{language}.yaml"


def _versioned(folder: Path, pattern: str) -> dict[str, Path]:
    found = {m.group(1): p for p in folder.glob("*.yaml") if (m := re.match(pattern, p.name))}
    return dict(sorted(found.items(), key=lambda kv: tuple(int(x) for x in kv[0].split("."))))


class LessonNotFound(LookupError):
    """No lesson of that name is installed, or a file declares none."""


@functools.cache
def _installed() -> dict[str, metadata.EntryPoint]:
    return {entry.name: entry for entry in metadata.entry_points(group=ENTRY_POINTS)}


def lesson_names() -> list[str]:
    """The names of every installed lesson, sorted."""
    return sorted(_installed())


@functools.cache
def lesson(name: str) -> Lesson:
    """The installed lesson called `name` (its entry point's object, which must be a Lesson of that name)."""
    entry = _installed().get(name)
    if entry is None:
        known = ", ".join(lesson_names()) or "none"
        raise LessonNotFound(f"no lesson {name!r} is installed (entry points {ENTRY_POINTS}: {known})")
    declared = entry.load()
    return _checked(declared, f"entry point {entry.name} = {entry.value}", name)


def lesson_of_kind(kind: str) -> Lesson:
    """The installed lesson that declares case kind `kind` (a stored spec names its kind, not its lesson). A kind is
    one lesson's: LessonNotFound when none or more than one installed lesson declares it."""
    owners = [name for name in lesson_names() if kind in lesson(name).case_kinds]
    if len(owners) != 1:
        raise LessonNotFound(f"case kind {kind!r} is declared by {len(owners)} installed lessons"
                             + (f" ({', '.join(owners)})" if owners else "") + ", not one")
    return lesson(owners[0])


def parse_spec(data: Mapping[str, Any]):
    """A stored case spec validated by the model its lesson declares for its `kind` (pydantic.ValidationError naming
    each bad field; LessonNotFound for a kind no installed lesson declares)."""
    kind = data.get("kind") if isinstance(data, Mapping) else None
    if not isinstance(kind, str):
        raise LessonNotFound("a case spec names its kind (\"kind\": one of the installed lessons' case kinds)")
    return lesson_of_kind(kind).case_kinds[kind].model_validate(data)


def sheet_lesson(data: Any) -> Lesson:
    """The installed lesson a sheet says it answers (its `lesson` field); pydantic.ValidationError at `lesson` naming
    the installed lessons when it names none of them, as any other bad field of a sheet is reported."""
    name = data.get("lesson") if isinstance(data, Mapping) else None
    if isinstance(name, str) and name in _installed():
        return lesson(name)
    from pydantic import ValidationError
    from pydantic_core import InitErrorDetails, PydanticCustomError

    known = " or ".join(repr(n) for n in lesson_names()) or "an installed lesson"
    if not isinstance(data, Mapping):
        detail = InitErrorDetails(type=PydanticCustomError("sheet_type", "a sheet is a mapping of lesson, student, "
                                                           "answers and configs"), loc=(), input=data)
    elif "lesson" not in data:
        detail = InitErrorDetails(type="missing", loc=("lesson",), input=data)
    else:
        detail = InitErrorDetails(type=PydanticCustomError("lesson", "Input should be {known} (the installed lessons)",
                                                           {"known": known}), loc=("lesson",), input=name)
    raise ValidationError.from_exception_data("PredictionSheet", [detail])


def parse_sheet(data: Any, part: str = "sheet"):
    """A sheet validated by the model of the lesson it names (`sheet_lesson`); `part` as Lesson.parse_sheet."""
    return sheet_lesson(data).parse_sheet(data, part)


def answered(sheet) -> tuple[str, ...]:
    """The item ids a sheet answers: all of its lesson's items, or one assignment's part."""
    return tuple(type(sheet.answers).model_fields)


def checkpoints_only(sheet) -> bool:
    """A sheet answering its lesson's concept checkpoints alone: it needs only the lesson's own cases."""
    return set(answered(sheet)) <= set(lesson(sheet.lesson).checkpoint_ids)


def case_metrics(spec, arrays: Mapping):
    """Every metric of one validated case of any installed lesson, by its kind's declaration."""
    return lesson_of_kind(spec.kind).case_metrics(spec, arrays)


def expected_arrays(spec) -> dict:
    """The arrays a valid result of `spec` holds, by its lesson's declaration."""
    return lesson_of_kind(spec.kind).expected_arrays(spec)


def parse_metrics(data: Mapping):
    """Stored metrics (metrics.json or a database column) back into the model its kind's lesson declares."""
    kind = data.get("kind") if isinstance(data, Mapping) else None
    if not isinstance(kind, str):
        raise LessonNotFound("stored metrics name their case kind (\"kind\")")
    return lesson_of_kind(kind).metrics_models[kind].model_validate(data)


def load_lesson(path: Path) -> Lesson:
    """The lesson a Python file declares as `LESSON` (a lesson author's package before it is installed: the file, or
    a folder holding `lesson.py`)."""
    path = path / "lesson.py" if path.is_dir() else path
    if not path.is_file():
        raise LessonNotFound(f"{path}: no such file (a lesson is declared by LESSON in a .py file, or in lesson.py of "
                             "its folder)")
    spec = importlib.util.spec_from_file_location(f"_lesson_{abs(hash(str(path.resolve())))}", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    declared = getattr(module, "LESSON", None)
    return _checked(declared, str(path), None)


def _checked(declared, origin: str, name: str | None) -> Lesson:
    if not isinstance(declared, Lesson):
        raise LessonNotFound(f"{origin}: LESSON is {type(declared).__name__}, not a rubric.lesson.Lesson")
    if name is not None and declared.name != name:
        raise LessonNotFound(f"{origin}: declares lesson {declared.name!r}, not {name!r}")
    if not re.match(NAME_PATTERN, declared.name):
        raise LessonNotFound(f"{origin}: name {declared.name!r} must be L and two digits (L02, L03)")
    return dataclasses.replace(declared, origin=origin)


__all__ = ["ENTRY_POINTS", "Lesson", "LessonNotFound", "SHEET_CASE_PREFIX", "SOURCE_LANGUAGE", "SeriesChart",
           "answered", "case_metrics", "checkpoints_only", "expected_arrays", "lesson", "lesson_names", "lesson_of_kind", "load_lesson",
           "parse_metrics", "parse_sheet", "parse_spec", "sheet_lesson"]
