"""tools.suite_durations adds up a JUnit XML run per folder of tests/ and names the slowest tests."""

from __future__ import annotations

from tools.suite_durations import main, per_folder

JUNIT = """<?xml version="1.0" encoding="utf-8"?>
<testsuites><testsuite name="pytest" tests="5">
<testcase classname="tests.grader.test_pages" name="test_a" time="1.5"/>
<testcase classname="tests.grader.test_pages.TestPage" name="test_b" time="2.25"><skipped message="x"/></testcase>
<testcase classname="tests.integration.test_audit" name="test_c" time="10.0"><failure message="y"/></testcase>
<testcase classname="tests.test_dates" name="test_d" time="0.5"/>
<testcase classname="tests.worker.test_figures" name="test_e" time="3"/>
</testsuite></testsuites>
"""


def test_seconds_and_counts_per_folder(tmp_path, capsys):
    path = tmp_path / "junit.xml"
    path.write_text(JUNIT)
    totals = per_folder(str(path))
    assert {k: (v["tests"], v["seconds"]) for k, v in totals.items()} == {
        "tests/grader": (2, 3.75), "tests/integration": (1, 10.0), "tests": (1, 0.5), "tests/worker": (1, 3.0)}
    assert (totals["tests/grader"]["skipped"], totals["tests/integration"]["failure"]) == (1, 1)
    assert main([str(path)]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[1].split()[:3] == ["tests/integration", "1", "10.0"]  # slowest first
    totals_end = lines.index(next(line for line in lines if line.startswith("all")))
    assert lines[totals_end].split()[:3] == ["all", "5", "17.2"]
    assert [line.split() for line in lines[totals_end + 3:totals_end + 5]] == [  # then the slowest tests, slowest first
        ["10.0", "tests.integration.test_audit::test_c"], ["3.0", "tests.worker.test_figures::test_e"]]
