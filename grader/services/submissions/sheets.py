"""The service layer's door to the rubric's prediction sheets: bound one's size before any work, parse one, list the
cases it needs measured, tell a checkpoint sheet apart. The rubric's sheet API can change in this one place."""

from __future__ import annotations

from typing import Any

import rubric
from grader.services.errors import Invalid
from rubric import lesson as lessons

# The caps every sheet (a submission's, a draft's, an imported YAML's) is held to before anything walks it. The largest
# sheet the lesson can take is well inside them (the reference sheet: 120 values, 26 keys in one mapping, 5 levels,
# 3 items in a list; an explanation holds at most 4000 characters), and every step that runs per key is linear, so
# the worst sheet they admit costs a bounded time to check, save, export or submit (tools/bench --only bounded).
MAX_KEYS = 64  # in one mapping (the answers have 26; a friction case's config 20 fields)
MAX_ITEMS = 16  # in one list (a friction case has at most 4 lanes)
MAX_DEPTH = 10  # sheet.configs.table_exercise.lanes.0.color.0 is 6 deep
MAX_TEXT = 4000  # characters in one text value (an explanation's limit)
MAX_KEY = 64  # characters in one key
# Values (mappings, lists and scalars) in the whole sheet; the reference sheet has 120, one with all six configs written
# out whole (four lanes) and every explanation 385. Each leaf of the form's configs is one input, so the form of any
# sheet within this posts far fewer than the 1000 fields a form may have (Starlette's max_fields).
MAX_VALUES = 500
MAX_ERRORS = 20


def size_problems(sheet: Any, prefix: str = "sheet") -> list[dict[str, str]]:
    """Why `sheet` is larger or odder than any sheet the lesson takes, as [{field, rule}] naming each path; [] when it
    is within every cap. Iterative and linear, and it stops at the first MAX_VALUES values, so it costs a bounded time
    whatever it is given. A key must be text without a dot: the form names each input by its dotted path, so
    `{a: 1, 'a.b': 2}` would give two inputs one path."""
    problems: list[dict[str, str]] = []
    stack: list[tuple[Any, str, int]] = [(sheet, prefix, 0)]
    seen = 0
    while stack and len(problems) < MAX_ERRORS:
        value, path, depth = stack.pop()
        seen += 1
        if seen > MAX_VALUES:
            problems.append({"field": prefix, "rule": f"at most {MAX_VALUES} values in all"})
            break
        if isinstance(value, str):
            if len(value) > MAX_TEXT:
                problems.append({"field": path, "rule": f"at most {MAX_TEXT} characters (this one has {len(value)})"})
        elif isinstance(value, dict | list) and depth >= MAX_DEPTH:
            problems.append({"field": path, "rule": f"nested at most {MAX_DEPTH} levels deep"})
        elif isinstance(value, dict):
            if len(value) > MAX_KEYS:
                problems.append({"field": path, "rule": f"at most {MAX_KEYS} keys (this one has {len(value)})"})
                continue
            for key, child in reversed(value.items()):
                where = f"{path}.{key}"
                if not isinstance(key, str) or not key or "." in key or len(key) > MAX_KEY:
                    problems.append({"field": f"{path}.{str(key)[:MAX_KEY]}", "rule": (
                        f"a key is 1 to {MAX_KEY} characters of text without a dot (a dotted path names a field)")})
                    continue
                stack.append((child, where, depth + 1))
        elif isinstance(value, list):
            if len(value) > MAX_ITEMS:
                problems.append({"field": path, "rule": f"at most {MAX_ITEMS} items (this one has {len(value)})"})
                continue
            stack.extend((child, f"{path}.{i}", depth + 1) for i, child in reversed(list(enumerate(value))))
    return problems


def check_size(sheet: Any, prefix: str = "sheet", detail: str = "invalid sheet") -> None:
    """Invalid naming each path past a cap (size_problems); nothing else is done with such a sheet."""
    if problems := size_problems(sheet, prefix):
        raise Invalid(detail, problems)


def parse_sheet(data: dict[str, Any], part: str = "sheet"):
    """The validated sheet, answering exactly the items named (an assignment's part, or the whole sheet); raises
    pydantic.ValidationError naming each bad item."""

    return rubric.parse_sheet(data, part)


def cases_to_run(sheet, book, variant=None) -> list:
    """The cases grading `sheet` under `book` (the course's rubric version, grader.core.rubrics.course_rubric) needs:
    the same version decides which configs obey the one-factor rule and so run, and then grades them. `variant`: the
    student's own lab (rubric.Variant) at an assignment with a pool; None: the lesson's shipped cases."""
    return list(rubric.cases_to_run(sheet, book, variant))


def checkpoints_only(sheet) -> bool:
    """A sheet answering concept checkpoints alone: it needs only the lesson's own cases, never a config of its own."""

    return lessons.checkpoints_only(sheet)
