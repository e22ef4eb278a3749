"""The lab check a grade stores, on real Genesis measurements: the submission's own runs of the check's cases, with
the output-location condition checked on the filesystem against ARTIFACTS_DIR rather than assumed."""

from __future__ import annotations

import dataclasses
import os
import shutil
import subprocess
from pathlib import Path

import pytest

from rubric import CHECK_CASES, load_rubric
from rubric.check import verdict_line
from grader.core.lab_check import submission_check

pytestmark = pytest.mark.slow


def holding(measured) -> Path:
    """The nearest folder that holds the measured case folders (under pytest-xdist the lesson is measured into a
    folder every test process shares)."""
    return Path(os.path.commonpath([r.out_dir for r in measured.values()]))


def _condition(outcome, cid):
    return next(c for c in outcome.conditions if c.id == cid)


def test_a_submission_with_every_check_case_passes_and_says_what_each_condition_means_here(measured):
    artifacts = holding(measured)
    outcome = submission_check(measured, artifacts_dir=artifacts, rubric=load_rubric("L03"), reused={"N1": 7})
    assert outcome.passed, "\n".join(f"{c.id}: {c.evidence}" for c in outcome.conditions if not c.passed)
    assert outcome.verdict_line == verdict_line(True) == "L03 CHECK: PASSED"
    # Evaluated on the check's cases only: the colour-swapped control and N5 are graded, not lab-check cases.
    assert list(outcome.backends) == list(CHECK_CASES)
    processes = _condition(outcome, "processes").evidence
    assert "Service run: N2, N3, N4, friction-baseline, friction-table-0.30 ran in the grading worker's" in processes
    assert "N1 (case run 7) reused identical earlier measurements" in processes
    assert "only the disabled branch" in _condition(outcome, "rendering").evidence
    outputs = _condition(outcome, "outputs").evidence
    assert "6 .npz files under ARTIFACTS_DIR" in outputs and "no image file written" in outputs
    assert "not inside a git work tree" in outputs and "ARTIFACTS_DIR" in outputs


def test_files_outside_artifacts_dir_fail_the_output_condition(measured, tmp_path):
    outcome = submission_check(measured, artifacts_dir=tmp_path, rubric=load_rubric("L03"))
    assert not outcome.passed and [c.id for c in outcome.conditions if not c.passed] == ["outputs"]
    assert "OUTSIDE ARTIFACTS_DIR" in _condition(outcome, "outputs").evidence
    assert outcome.verdict_line == verdict_line(False, [_condition(outcome, "outputs").title])


@pytest.mark.parametrize("ignored", [False, True])
def test_an_artifacts_dir_inside_a_git_work_tree_must_be_ignored_by_it(measured, tmp_path, ignored):
    repo = tmp_path / "repo"
    artifacts = repo / "var" / "artifacts"
    subprocess.run(["git", "init", "-q", str(repo)], check=True)
    if ignored:
        (repo / ".gitignore").write_text("var/\n")
    results = {}
    for name in CHECK_CASES:
        folder = artifacts / "case-runs" / name
        shutil.copytree(measured[name].out_dir, folder)
        results[name] = dataclasses.replace(measured[name], out_dir=str(folder))
    outcome = submission_check(results, artifacts_dir=artifacts, rubric=load_rubric("L03"))
    outputs = _condition(outcome, "outputs")
    assert outputs.passed is ignored, outputs.evidence
    assert ("ignored by git and nothing under it tracked" if ignored else "NOT ignored by git") in outputs.evidence


def test_a_missing_check_case_is_reported_not_run(measured):
    partial = {name: r for name, r in measured.items() if name != "friction-table-0.30"}
    outcome = submission_check(partial, artifacts_dir=holding(measured), rubric=load_rubric("L03"))
    assert not outcome.passed
    assert [c.id for c in outcome.conditions if not c.passed] == ["table_friction_change"]
    assert "friction-table-0.30" in _condition(outcome, "table_friction_change").evidence


def test_the_lab_check_of_a_grade_never_imports_genesis_or_torch():
    from tests.factories import heavy_imports

    assert heavy_imports(["grader.core.lab_check", "worker.grading"]) == []
