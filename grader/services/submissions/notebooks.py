"""A Jupyter notebook as a sheet: its tagged answer and config cells read with nbformat and parsed as Python literals,
never executed; what it holds becomes the sheet the other doors send, submitted through the same `submit`."""

from __future__ import annotations

import ast
import json
import re
from dataclasses import dataclass, field
from typing import Any

import nbformat
from sqlalchemy.orm import Session

from grader import i18n
from grader.core.models import Assignment, Submission, User, utcnow
from grader.core.rubrics import course_rubric
from grader.services.errors import Invalid, Refused
from grader.services.sending import Sender
from grader.services.setup import assignments
from grader.services.submissions import drafts, sheet_form, sheets
from grader.services.submissions import submit as submissions

# A notebook is read whole before anything else: the app's body limit (settings.max_body_bytes) bounds an upload first.
MAX_BYTES = 1_000_000
# What the cells' outputs may hold in all: nothing here reads them, so a plot or a long log is only weight to carry.
MAX_OUTPUT_BYTES = 200_000
MAX_CELLS = 1_000
# An answer cell holds one item's answer: the longest the lesson takes is a few explanations of MAX_TEXT characters.
MAX_SOURCE = 20_000
# `answer:A2` or `config:extension` as a cell tag; or the cell's metadata {"grader": {"answer": "A2"}}.
TAG = re.compile(r"^(answer|config):([A-Za-z][A-Za-z0-9_]{0,63})$")
KINDS = {"answer": "answers", "config": "configs"}
DETAIL = "invalid notebook"


@dataclass(frozen=True)
class Cell:
    """One tagged cell: its place (counted from 1, as a reader counts down the notebook) and what it answers."""

    number: int
    kind: str  # "answer" or "config"
    key: str  # the item id or the config's role

    @property
    def words(self) -> str:
        return f"cell {self.number} ({self.kind}:{self.key})"


@dataclass
class ReadNotebook:
    """What a notebook holds: answers by item, configs by role, the lesson its metadata names, and each tagged cell."""

    answers: dict[str, Any] = field(default_factory=dict)
    configs: dict[str, Any] = field(default_factory=dict)
    lesson: str | None = None
    cells: dict[tuple[str, str], Cell] = field(default_factory=dict)

    def sheet(self, *, student: str, lesson: str | None) -> dict[str, Any]:
        """The sheet the API takes: the metadata's lesson (else `lesson`), the student's name, answers and configs."""
        sheet: dict[str, Any] = {"lesson": self.lesson or lesson, "student": student, "answers": self.answers}
        if self.configs:
            sheet["configs"] = self.configs
        return sheet

    def cell_of(self, path: str) -> Cell | None:
        """The cell a sheet path (`sheet.answers.A2.direction`) comes from, if a cell holds it."""
        parts = path.removeprefix("sheet.").split(".")
        if len(parts) >= 2 and parts[0] in ("answers", "configs"):
            return self.cells.get(("answer" if parts[0] == "answers" else "config", parts[1]))
        return None


def _refuse(rule: str, where: str = "notebook") -> Invalid:
    return Invalid(DETAIL, [{"field": where, "rule": rule}])


def _tagged(cell: dict) -> list[tuple[str, str]]:
    """(kind, key) of every answer or config mark on a cell: its tags and its `grader` metadata."""
    marks = []
    for tag in cell.get("metadata", {}).get("tags", []) or []:
        if isinstance(tag, str) and (match := TAG.match(tag.strip())):
            marks.append((match[1], match[2]))
    grader = cell.get("metadata", {}).get("grader")
    if isinstance(grader, dict):
        for kind in KINDS:
            if isinstance(grader.get(kind), str) and TAG.match(f"{kind}:{grader[kind]}"):
                marks.append((kind, grader[kind]))
    return list(dict.fromkeys(marks))


def _source(cell: dict) -> str:
    source = cell.get("source", "")
    return "".join(source) if isinstance(source, list) else source


def literal_of(source: str, cell: Cell) -> Any:
    """The value a cell assigns: one statement `KEY = <literal>` (numbers, text, True/False/None, lists, dicts),
    comments around it. Parsed with ast and ast.literal_eval: nothing in it runs. Invalid naming the cell and line."""
    where = f"notebook.cells.{cell.number}"
    if len(source) > MAX_SOURCE:
        raise _refuse(f"{cell.words}: at most {MAX_SOURCE} characters (this one has {len(source)})", where)
    try:
        tree = ast.parse(source)
    except SyntaxError as exc:
        line = f", line {exc.lineno}" if exc.lineno else ""
        raise _refuse(f"{cell.words}{line}: not Python: {exc.msg}", where) from None
    except (ValueError, RecursionError, MemoryError):  # a NUL byte; nesting deeper than the parser goes
        raise _refuse(f"{cell.words}: not Python this service reads (a NUL byte, or nested too deep)", where) from None
    statements = tree.body
    if len(statements) != 1 or not isinstance(statements[0], ast.Assign) or len(statements[0].targets) != 1 \
            or not isinstance(statements[0].targets[0], ast.Name):
        raise _refuse(f"{cell.words}: must hold one assignment, `{cell.key} = {{...}}`, and comments", where)
    target = statements[0].targets[0].id
    if target != cell.key:
        raise _refuse(f"{cell.words}: assigns {target}, but its tag says {cell.key}: `{cell.key} = {{...}}`", where)
    try:
        return ast.literal_eval(statements[0].value)
    except (ValueError, TypeError, SyntaxError, MemoryError, RecursionError):
        raise _refuse(f"{cell.words}, line {statements[0].value.lineno}: only literal values (numbers, text in quotes, "
                      "True/False, lists [...], dicts {...}); no names, calls or arithmetic", where) from None


def _notebook(data: bytes) -> dict:
    """The notebook's JSON as nbformat 4 validates it; Invalid saying why it is not one."""
    if len(data) > MAX_BYTES:
        raise _refuse(f"at most {MAX_BYTES} bytes (this file has {len(data)}): clear the outputs and upload again")
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError:
        raise _refuse("not a notebook: a .ipynb file is UTF-8 text (JSON)") from None
    try:
        raw = json.loads(text)
    except (json.JSONDecodeError, RecursionError) as exc:
        where = f" (line {exc.lineno}, column {exc.colno}: {exc.msg})" if isinstance(exc, json.JSONDecodeError) else ""
        raise _refuse(f"not a notebook: not JSON{where}; upload the .ipynb file Jupyter saves") from None
    if not isinstance(raw, dict) or "nbformat" not in raw:
        raise _refuse("not a notebook: a .ipynb file is a JSON object with nbformat and cells")
    if raw.get("nbformat") != 4:
        raise _refuse(f"nbformat {raw.get('nbformat')!r}: only version 4 notebooks are read (Jupyter 4 and later save "
                      "them: open it in Jupyter and save it again)", "notebook.nbformat")
    cells = raw.get("cells")
    if isinstance(cells, list) and len(cells) > MAX_CELLS:
        raise _refuse(f"at most {MAX_CELLS} cells (this one has {len(cells)})", "notebook.cells")
    try:
        node = nbformat.from_dict(raw)
        nbformat.validate(node)
    except nbformat.ValidationError as exc:
        path = ".".join(str(p) for p in exc.absolute_path) if getattr(exc, "absolute_path", None) else ""
        raise _refuse(f"not a valid nbformat 4 notebook{' at ' + path if path else ''}: {str(exc.message)[:200]}",
                      "notebook") from None
    outputs = sum(len(json.dumps(c.get("outputs", []))) for c in raw["cells"])
    if outputs > MAX_OUTPUT_BYTES:
        raise _refuse(f"the cells' outputs take {outputs} bytes (at most {MAX_OUTPUT_BYTES}): clear them (Edit › Clear "
                      "Outputs of All Cells), save, and upload again; no output is read", "notebook.outputs")
    return raw


def read(data: bytes) -> ReadNotebook:
    """The answers and configs a notebook's tagged cells hold; Invalid naming the file's or the cell's problem: not
    JSON, not nbformat 4, outputs past MAX_OUTPUT_BYTES, no answer cell, two cells for one item, a cell that is not
    one literal assignment. Nothing in the notebook is executed."""
    raw = _notebook(data)
    found = ReadNotebook()
    grader = raw.get("metadata", {}).get("grader")
    if isinstance(grader, dict) and isinstance(grader.get("lesson"), str):
        found.lesson = grader["lesson"]
    for number, cell in enumerate(raw["cells"], start=1):
        marks = _tagged(cell)
        if not marks:
            continue
        if len(marks) > 1:
            raise _refuse(f"cell {number} is marked {len(marks)} times ("
                          + ", ".join(f"{k}:{v}" for k, v in marks) + "): one mark a cell",
                          f"notebook.cells.{number}")
        kind, key = marks[0]
        here = Cell(number, kind, key)
        if cell.get("cell_type") != "code":
            raise _refuse(f"{here.words} is a {cell.get('cell_type')} cell: an answer cell is a code cell",
                          f"notebook.cells.{number}")
        if (kind, key) in found.cells:
            first = found.cells[kind, key]
            raise _refuse(f"cells {first.number} and {number} both hold {kind}:{key}: keep one",
                          f"notebook.cells.{number}")
        found.cells[kind, key] = here
        getattr(found, KINDS[kind])[key] = literal_of(_source(cell), here)
    if not found.answers:
        raise _refuse("no answer cell: tag each answer's code cell answer:ID (e.g. answer:A2) as the "
                      "lesson's template notebook does (docs/student.md)", "notebook.cells")
    return found


def with_cells(exc: Invalid, notebook: ReadNotebook) -> Invalid:
    """The sheet's errors (`sheet.answers.A2.direction: ...`) with the cell each comes from named in the rule."""
    errors = []
    for error in exc.errors:
        cell = notebook.cell_of(error.get("field", ""))
        errors.append(error | {"rule": f"{cell.words}: {error['rule']}"} if cell is not None else error)
    exc.errors = errors
    return exc


def submit(*, session: Session, user: User, data: bytes, assignment_id: int | None, sender: Sender,
           lesson: str | None = None) -> Submission:
    """Submit the notebook's answers as a sheet through the service's own `submit` (every rule is its: role, rate,
    assignment, variant, sheet); `lesson` when the notebook's metadata names none (an assignment's). Invalid naming the
    file's or the cell's problem, and nothing is stored then."""
    notebook = read(data)
    if lesson is None and assignment_id is not None:  # an unknown one: submit refuses it by its own rule
        assignment = session.get(Assignment, assignment_id)
        lesson = assignment.lesson if assignment is not None and assignment.course_id == user.course_id else None
    sheet = notebook.sheet(student=user.name, lesson=lesson)
    try:
        return submissions.submit(session=session, user=user, sheet=sheet, assignment_id=assignment_id, sender=sender)
    except Invalid as exc:
        raise with_cells(exc, notebook) from None


# --- the notebook client's door (the `gradernb` package): the sheet form's facts as data -----------------------------

@dataclass(frozen=True)
class SheetView:
    """What the sheet page shows a user at an assignment, as data: its items with their fields (sheet paths, words,
    choices, units; a student on a variant reads their own numbers), the config roles it takes with their rules, the
    draft the page keeps, and what a submission now would be (`standing`: attempt, lateness, penalty, or the rule)."""

    assignment: Assignment
    part: str
    lesson: str
    items: list[dict]
    configs: list[dict]
    draft: dict
    standing: dict


def _standing(session: Session, user: User, assignment: Assignment) -> dict:
    try:
        attempt, late = assignments.admit(session=session, assignment=assignment, student=user, now=utcnow())
    except Refused as exc:
        return {"refused": exc.rule, "reason": exc.reason}
    return {"attempt": attempt, "max_attempts": assignment.max_attempts, "late_seconds": late,
            "late": assignments.late_text(late), "penalty": assignments.penalty_fraction(assignment, late)}


def _items(book, assignment: Assignment, variant, locale: str) -> list[sheet_form.ItemForm]:
    return sheet_form.item_forms(book, assignments.item_ids(assignment.lesson, assignment.part), variant, locale)


def _words(item: sheet_form.ItemForm, field: sheet_form.Input, variant, locale: str, lesson: str) -> str:
    label = (sheet_form.answer_label(field.label, variant, locale) if variant is not None
             else i18n.lesson_word(locale, "labels", field.label, lesson))
    return f"{item.id} {label}"


def sheet_view(*, session: Session, user: User, assignment: Assignment, locale: str = "en") -> SheetView:
    """The sheet page's facts for `user` at `assignment` (one of their course's), in `locale`: Conflict while their lab
    (a variant pool) is being prepared, as on the page."""
    variant = sheet_form.form_variant(session=session, assignment=assignment, user=user)
    book = course_rubric(session, user.course_id, assignment.lesson)
    items = [{"id": item.id, "part": item.part,
              "question": item.question if item.localized else i18n.lesson_word(locale, "questions", item.question,
                                                                                assignment.lesson),
              "fields": [{"path": f.name, "words": _words(item, f, variant, locale, assignment.lesson),
                          "widget": f.widget, "choices": list(f.choices), "units": list(f.units),
                          "required": f.required} for f in item.inputs]}
             for item in _items(book, assignment, variant, locale)]
    roles = sheet_form.form_configs(book) if sheet_form.has_configs(assignment.part) else ()
    configs = [{"role": role, "baseline": book.configs[role].baseline,
                "may_change": list(book.configs[role].may_change),
                "rule": i18n.lesson_word(locale, "configs", book.configs[role].description, assignment.lesson)}
               for role in roles if role in book.configs]
    draft = drafts.load(session=session, user=user, assignment=assignment)
    return SheetView(assignment=assignment, part=assignment.part, lesson=assignment.lesson, items=items,
                     configs=configs, draft=draft.sheet if draft is not None else
                     {"lesson": assignment.lesson, "student": user.name, "answers": {}},
                     standing=_standing(session, user, assignment))


def _error_words(error: dict, items: list[sheet_form.ItemForm], variant, locale: str, lesson: str) -> str:
    """The field an error names in the student's words: `sheet.answers.A2.direction` -> "A2 direction"."""
    path = error.get("field", "").removeprefix("sheet.")
    for item in items:
        for f in item.inputs:
            if path == f.name or path.startswith(f.name + "."):
                return _words(item, f, variant, locale, lesson)
        if path == f"answers.{item.id}" or path.startswith(f"answers.{item.id}."):
            return item.id
    if path.startswith("configs."):
        role, _, rest = path.removeprefix("configs.").partition(".")
        return f"{i18n.lesson_word(locale, 'roles', role.replace('_', ' '), lesson)}{': ' + rest if rest else ''}"
    return path


def check(*, session: Session, user: User, assignment: Assignment, sheet: Any, locale: str = "en") -> dict:
    """The sheet form's Check, as data: the sheet's errors under the submission's own rules (each with its field in
    the student's words), each config's one-factor verdict against the student's own baseline with the items a broken
    one voids, and whether the sheet passes every rule. Nothing is saved."""
    sheets.check_size(sheet)
    if not isinstance(sheet, dict):
        raise Invalid("invalid sheet", [{"field": "sheet", "rule": "must be a mapping"}])
    variant = sheet_form.form_variant(session=session, assignment=assignment, user=user)
    book = course_rubric(session, user.course_id, assignment.lesson)
    items = _items(book, assignment, variant, locale)
    errors = sheet_form.problems(sheet, assignment.part)
    checks = []
    if sheet_form.has_configs(assignment.part):
        checks, config_errors = sheet_form.config_checks(session=session, sheet=sheet, part=assignment.part,
                                                         book=book, variant=variant)
        errors += [e for e in config_errors if e not in errors]
    change = lambda c: {"field": c.field, "baseline": c.baseline, "yours": c.config, "visual": c.visual}  # noqa: E731
    return {
        "passes": not errors and not any(c.violations for c in checks),
        "errors": [e | {"words": _error_words(e, items, variant, locale, assignment.lesson)} for e in errors],
        "configs": [{"role": c.role, "baseline": c.baseline, "may_change": c.may_change, "verdict": c.verdict,
                     "one_factor": not c.violations, "changes": [change(x) for x in c.changes],
                     "violations": [x.field for x in c.violations], "voids": c.voids} for c in checks],
    }
