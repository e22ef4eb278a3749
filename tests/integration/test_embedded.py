"""`grader run --exit-after-grading`: the embedded default grades the example sheet with no Redis or PostgreSQL."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

from rubric import load_rubric
from tests import services

pytestmark = [pytest.mark.slow]


def test_embedded_run_grades_the_example_sheet_without_servers(tmp_path):
    env = {k: v for k, v in os.environ.items() if k not in ("DATABASE_URL", "BROKER_URL", "ARTIFACTS_DIR")}
    env.update(DATA_DIR=str(tmp_path / "data"), PYTHONPATH=str(services.ROOT))
    port = services.free_port()
    done = subprocess.run(
        [sys.executable, "-c", "from grader.cli.service import run; run()", "--exit-after-grading", "--port", str(port)],
        cwd=services.ROOT, env=env, capture_output=True, text=True, timeout=900,
    )
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    out = done.stdout
    assert "database sqlite:///" in out and "broker filesystem://" in out
    assert f"API at http://127.0.0.1:{port}" in out and "GRADE " in out
    report = tmp_path / "data" / "reports" / "submission-1" / "grade.json"
    assert f"report: {report}" in out
    grade = json.loads(report.read_text())
    # The example sheet is the reference answer: every item of the current rubric at its full points.
    rubric = load_rubric("L03")
    full_marks = sum(item.points for item in rubric.items)
    assert (grade["rubric_version"], grade["rubric_hash"]) == (rubric.version, rubric.content_hash)
    assert {i["id"]: i["max_score"] for i in grade["items"]} == {item.id: item.points for item in rubric.items}
    short = [(i["id"], i["verdict"], i["feedback"]) for i in grade["items"]
             if i["verdict"] != "credit" or i["score"] != i["max_score"]]
    assert not short, short
    assert grade["total"] == grade["max_total"] == full_marks
    assert f"GRADE {full_marks:g} / {full_marks:g}" in out
    runs = json.loads((report.parent / "case-runs.json").read_text())
    assert runs and all(r["status"] == "done" and r["provenance"]["actual_backend"] == "cpu" for r in runs)
    assert (tmp_path / "data" / "grader.db").is_file()
