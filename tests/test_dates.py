"""No test depends on the calendar: a literal date in a test is allowed only where the service's clock is frozen.

A literal due, open or close time (or any instant the service compares with "now") means something else on every
day the suite runs: `test_refusals_and_pages_show_times_in_the_course_zone` wrote a hard close of 2026-11-24 beside
a due date of two days ago and failed from 2026-11-26 on. Such a test freezes the clock with
`@pytest.mark.clock("...")` (tests/conftest.py; on the test, its class, or the module's `pytestmark`), or writes its
times relative to the clock (`clock.now() + timedelta(...)`). A date the service never compares with now (a CSV's
formatting, a review date, a night the clocks change) says so on its line: `# not a clock time: <why>`.
Docstrings and comments are not looked at.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

TESTS = Path(__file__).parent
PRAGMA = "# not a clock time"
DATE = re.compile(r"(?<!\d)(19|20)\d\d-[01]\d-[0-3]\d(?!\d)")


def _is_clock_mark(node: ast.expr) -> bool:
    """`pytest.mark.clock(...)` or `mark.clock(...)`."""
    return (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and node.func.attr == "clock"
            and isinstance(node.func.value, ast.Attribute) and node.func.value.attr == "mark")


def _module_frozen(tree: ast.Module) -> bool:
    for node in tree.body:
        if isinstance(node, ast.Assign) and any(isinstance(t, ast.Name) and t.id == "pytestmark" for t in node.targets):
            marks = node.value.elts if isinstance(node.value, (ast.List, ast.Tuple)) else [node.value]
            if any(_is_clock_mark(m) for m in marks):
                return True
    return False


def _docstrings(tree: ast.Module) -> set[int]:
    """ids of the string constants that are docstrings."""
    out = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)) and node.body:
            first = node.body[0]
            if isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant):
                out.add(id(first.value))
    return out


def _literal_dates(node: ast.AST, skip: set[int]) -> list[tuple[int, str]]:
    """(line, text) of each date written literally under `node`: a string like 2026-11-24 or datetime(2026, ...)."""
    found = []
    for child in ast.walk(node):
        if isinstance(child, ast.Constant) and isinstance(child.value, str) and id(child) not in skip:
            if m := DATE.search(child.value):
                found.append((child.lineno, m.group(0)))
        elif (isinstance(child, ast.Call) and getattr(child.func, "id", getattr(child.func, "attr", None)) in (
                "datetime", "date") and child.args and isinstance(child.args[0], ast.Constant)
              and isinstance(child.args[0].value, int) and 1900 <= child.args[0].value <= 2100):
            found.append((child.lineno, f"{child.func.id if isinstance(child.func, ast.Name) else child.func.attr}"
                                        f"({child.args[0].value}, ...)"))
    return found


def unfrozen_dates(source: str) -> list[tuple[int, str]]:
    """The literal dates of a test module that no frozen clock covers."""
    tree = ast.parse(source)
    if _module_frozen(tree):
        return []
    frozen_lines = set()  # the lines of every test or class that freezes the clock
    for node in ast.walk(tree):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)) and any(
                _is_clock_mark(d) for d in node.decorator_list):
            start = min([node.lineno] + [d.lineno for d in node.decorator_list])
            frozen_lines |= set(range(start, (node.end_lineno or node.lineno) + 1))
    lines = source.splitlines()
    return [(line, text) for line, text in _literal_dates(tree, _docstrings(tree))
            if line not in frozen_lines and PRAGMA not in lines[line - 1]]


def test_no_literal_date_without_a_frozen_clock():
    offenders = []
    for path in sorted(p for p in TESTS.rglob("*.py") if p.resolve() != Path(__file__).resolve()):
        for line, text in unfrozen_dates(path.read_text(encoding="utf-8")):
            offenders.append(f"{path.relative_to(TESTS.parent)}:{line}: {text}")
    assert not offenders, ("literal dates in tests without @pytest.mark.clock(...) (tests/conftest.py); freeze the "
                           "clock or write them relative to grader.core.clock.now():\n" + "\n".join(offenders))


@pytest.mark.parametrize("source, found", [
    ('def test_a(api):\n    create(api, due_at="2026-11-24T10:00:00Z")\n', [(2, "2026-11-24")]),
    ('def test_a():\n    x = datetime(2027, 1, 1)\n', [(2, "datetime(2027, ...)")]),
    ('FORM = {"due_at": "2026-12-08T10:00"}\n', [(1, "2026-12-08")]),
    ('@pytest.mark.clock("2026-11-20T12:00:00Z")\ndef test_a(api):\n    create(api, due_at="2026-11-24")\n', []),
    ('import pytest\npytestmark = [pytest.mark.clock("2026-11-20T12:00:00Z")]\nFORM = {"due_at": "2026-12-08"}\n', []),
    ('def test_a():\n    """Seen on 2026-11-27."""\n    x = 1  # 2026-11-27\n', []),
    ('def test_a():\n    csv(datetime(2026, 1, 2))  # not a clock time: formatting only\n', []),
    ('@pytest.mark.parametrize("d", ["2026-11-24"])\n@pytest.mark.clock("2026-11-20T12:00:00Z")\ndef test_a(d):\n    pass\n',
     []),
    ('def test_a():\n    csv(datetime(2026, 1, 2))  # formatting only\n', [(2, "datetime(2026, ...)")]),
])
def test_the_lint_finds_exactly_the_unfrozen_dates(source, found):
    assert unfrozen_dates(source) == found
