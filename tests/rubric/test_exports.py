"""Exports checked against their formats: the class CSV and Gradescope's results.json."""

from __future__ import annotations

import csv
import dataclasses
import io
import json

import pytest

from rubric import grade_sheet, grades_csv, gradescope_results, load_rubric, parse_sheet
from rubric.exports import CSV_FIXED_COLUMNS
from rubric.scoring import SHEET_CASE_PREFIX
from tests.factories import reference_sheet, sheet_results

GRADESCOPE_TOP = {"score", "execution_time", "output", "tests"}
GRADESCOPE_TEST = {"name", "score", "max_score", "output", "visibility"}


@pytest.fixture(scope="module")
def reports(measured):
    data = reference_sheet()
    results = sheet_results(measured)
    good = grade_sheet(parse_sheet(data), results)
    data["student"], data["answers"]["A4"]["same_length"] = "bob", True
    bob = grade_sheet(parse_sheet(data), results)
    # carol: the friction baseline failed (not_measured items) and her extension measured exactly N1's
    # trajectory (a zero proxy difference: X2 inconclusive, not counted)
    data["student"] = "carol"
    partial = {k: v for k, v in results.items() if k != "friction-baseline"}
    partial[SHEET_CASE_PREFIX + "extension"] = dataclasses.replace(measured["N1"], spec=measured["N5"].spec)
    carol = grade_sheet(parse_sheet(data), partial)
    return [("alice", good), ("bob", bob), ("carol", carol)]


def test_csv_has_one_row_per_student_and_one_column_per_item(reports):
    rows = list(csv.DictReader(io.StringIO(grades_csv(reports))))
    item_ids = [i.id for i in load_rubric("L03").items]
    assert list(rows[0]) == [*CSV_FIXED_COLUMNS, *item_ids]
    assert [r["student"] for r in rows] == ["alice", "bob", "carol"]
    for row, (_, report) in zip(rows, reports):
        assert float(row["total"]) == report.total and float(row["max_total"]) == report.max_total
        assert row["rubric_version"] == report.rubric_version
        assert sum(float(row[i]) for i in item_ids if row[i]) == report.total
        for item in report.items:
            assert (row[item.id] == "") == (item.verdict == "inconclusive")
    assert rows[1]["A4"] == "0" and rows[0]["A4"] == "1"
    assert rows[2]["complete"] == "false" and rows[2]["H4"] == "0" and rows[2]["X2"] == ""


def test_csv_quotes_awkward_student_ids(reports):
    name, report = reports[0]
    text = grades_csv([("doe, jane", report)])
    assert list(csv.DictReader(io.StringIO(text)))[0]["student"] == "doe, jane"


def test_gradescope_results_follow_the_format(reports):
    _, report = reports[1]
    results = gradescope_results(report, execution_time=12.3456)
    assert set(results) == GRADESCOPE_TOP
    json.dumps(results)  # must be plain JSON
    assert results["score"] == report.total and results["execution_time"] == 12.346
    assert f"rubric version {report.rubric_version} " in results["output"]
    assert len(results["tests"]) == len(report.items)
    for test, item in zip(results["tests"], report.items):
        assert set(test) == GRADESCOPE_TEST
        assert test["name"].startswith(f"{item.id}: ")
        assert (test["score"], test["max_score"]) == (item.score, item.max_score)
        assert test["visibility"] in {"hidden", "after_due_date", "after_published", "visible"}
        assert test["output"] == item.feedback
    assert sum(t["score"] for t in results["tests"]) == results["score"]


def test_gradescope_output_flags_unmeasured_items(reports):
    _, carol = reports[2]
    assert "could not be measured" in gradescope_results(carol, 1.0)["output"]
    with pytest.raises(ValueError, match="execution_time"):
        gradescope_results(carol, -1.0)
