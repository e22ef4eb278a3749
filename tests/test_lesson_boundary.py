"""The lesson boundary, scanned in the source (issue 45, item 3): the service (grader/, worker/) is to name none of a
lesson's cases, metrics or items and import none of its modules; the lesson's declaration (rubric.lesson.Lesson,
found by entry point) is how it reads them. L03 still runs through both folders, so this is a ratchet while L03 moves
behind its declaration: each file may hold at most the L03 names and imports it held when the scan was written
(ALLOWED, beside this file), a file not listed none. A file that holds fewer fails too, with the figure to write
down, so the allowance only ever goes down and the closing notes can quote it. The import-linter contracts
(pyproject.toml) keep the layers; this scan sees what an import graph cannot: a case's name in a string.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
ALLOWED = Path(__file__).with_name("lesson_boundary_allowed.json")
# L03's own names: its cases, the lanes of its friction scene, its metrics' best-known field, its config roles, the
# lesson's name, and its modules (still under rubric/ until they move into the lesson's package).
L03_NAMES = re.compile(r"\"N[1-5]\"|'N[1-5]'|friction-baseline|friction-table|penetration_proxy|\bL03\b|\blanes?\b"
                       r"|colors-swapped|table_exercise")
L03_IMPORTS = re.compile(r"^\s*(?:from|import) rubric\.(?:cases|specs|metrics|friction|check|sheet|scoring|l03|"
                         r"one_factor|relations|analysis|variants|copying)\b", re.M)


def scan() -> dict[str, int]:
    """{file under grader/ or worker/: how many L03 names and L03 module imports it holds}, files holding none left
    out."""
    counts = {}
    for folder in ("grader", "worker"):
        for path in sorted((ROOT / folder).rglob("*.py")):
            text = path.read_text()
            n = len(L03_NAMES.findall(text)) + len(L03_IMPORTS.findall(text))
            if n:
                counts[str(path.relative_to(ROOT))] = n
    return counts


def test_the_service_names_no_more_of_l03_than_it_did():
    allowed, found = json.loads(ALLOWED.read_text()), scan()
    grown = {f: (n, allowed.get(f, 0)) for f, n in found.items() if n > allowed.get(f, 0)}
    assert not grown, ("these files name more of L03 than allowed (found, allowed); read it through the lesson's "
                       f"declaration (rubric.lesson) instead: {grown}")
    shrunk = {f: (found.get(f, 0), n) for f, n in allowed.items() if found.get(f, 0) < n}
    assert not shrunk, (f"progress: lower these allowances in {ALLOWED.name} to what was found (found, allowed): "
                        f"{shrunk}")


def test_the_scan_sees_a_case_name_and_a_lesson_import(tmp_path, monkeypatch):
    """The scan itself: a string naming a case and an import of a lesson module each count."""
    (tmp_path / "grader").mkdir()
    (tmp_path / "worker").mkdir()
    (tmp_path / "grader" / "a.py").write_text('from rubric.friction import pair\nNAME = "friction-baseline"\n')
    (tmp_path / "worker" / "b.py").write_text("from rubric.lesson import lesson\n")  # the declaration: allowed
    monkeypatch.setattr(__import__(__name__, fromlist=["ROOT"]), "ROOT", tmp_path)
    assert scan() == {"grader/a.py": 2}
