"""The suite's time per folder of tests/, from the JUnit XML of a run (issue 37: the closing note and
docs/operator.md quote it).

    .venv/bin/python -m pytest -n 2 --dist loadgroup --junitxml=out/junit.xml tests/...
    .venv/bin/python -m tools.suite_durations out/junit.xml

Each test's time is pytest's JUnit "total" (setup, call and teardown, so a module fixture's cost counts in the first
test that builds it). Under pytest-xdist the tests of both processes are added up: the sum is test-process time,
about twice the wall time on two processes, not the run's wall time.
"""

from __future__ import annotations

import sys
import xml.etree.ElementTree as ET
from collections import defaultdict


def folder_of(testcase: ET.Element) -> str:
    """`tests/grader` for classname tests.grader.test_x(.Class); `tests` for a module directly under tests/."""
    parts = (testcase.get("file") or testcase.get("classname", "").replace(".", "/")).split("/")
    if len(parts) > 2 and parts[0] == "tests" and not parts[1].startswith("test_"):
        return "/".join(parts[:2])
    return parts[0] or "?"


def per_folder(path: str) -> dict[str, dict[str, float]]:
    totals: dict[str, dict[str, float]] = defaultdict(lambda: defaultdict(float))
    for case in ET.parse(path).getroot().iter("testcase"):
        row = totals[folder_of(case)]
        row["seconds"] += float(case.get("time") or 0)
        row["tests"] += 1
        outcome = next((child.tag for child in case if child.tag in ("failure", "error", "skipped")), "passed")
        row[outcome] += 1
    return totals


SLOWEST = 15  # the tests listed after the folders: where a minute of the suite can be won


def slowest(path: str, count: int = SLOWEST) -> list[tuple[float, str]]:
    """The `count` slowest tests of the run: (seconds, classname::name), slowest first."""
    cases = [(float(case.get("time") or 0), f"{case.get('classname')}::{case.get('name')}")
             for case in ET.parse(path).getroot().iter("testcase")]
    return sorted(cases, reverse=True)[:count]


def main(argv: list[str]) -> int:
    if len(argv) != 1:
        print(__doc__.strip(), file=sys.stderr)
        return 2
    totals = per_folder(argv[0])
    print(f"{'folder':<20} {'tests':>6} {'seconds':>9} {'minutes':>8}  not passed")
    for folder, row in sorted(totals.items(), key=lambda kv: -kv[1]["seconds"]):
        bad = ", ".join(f"{int(row[k])} {k}" for k in ("failure", "error", "skipped") if row[k])
        print(f"{folder:<20} {int(row['tests']):>6} {row['seconds']:>9.1f} {row['seconds'] / 60:>8.1f}  {bad}")
    seconds = sum(row["seconds"] for row in totals.values())
    print(f"{'all':<20} {int(sum(r['tests'] for r in totals.values())):>6} {seconds:>9.1f} {seconds / 60:>8.1f}")
    print(f"\nthe {SLOWEST} slowest tests (seconds, setup to teardown):")
    for took, name in slowest(argv[0]):
        print(f"{took:>9.1f}  {name}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
