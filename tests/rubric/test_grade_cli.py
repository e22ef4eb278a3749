"""`grader grade`: files, printed items and exit codes, with the engine replaced by this session's measurements."""

from __future__ import annotations

import copy
import csv
import dataclasses
import io
import json
from pathlib import Path

import pytest
import yaml
from click.testing import CliRunner

from grader.cli import grade as grade_module
from grader.cli.grade import grade
from rubric import CaseResult, GradeReport, load_rubric
from rubric import field_changes
from tests.factories import REFERENCE_YAML, reference_sheet

REFERENCE = reference_sheet()


@pytest.fixture
def engine(measured, monkeypatch):
    """Answer each case with the session measurement of an identical spec (names aside), else a failed result."""
    asked = []

    def execute(specs, out_root, mode, progress):
        results = {}
        for spec in specs:
            asked.append(spec.name)
            same = next((r for r in measured.values()
                         if type(r.spec) is type(spec) and not field_changes(r.spec, spec)), None)
            result = dataclasses.replace(same, spec=spec) if same else CaseResult(
                spec=spec, status="failed", error="no recorded measurement for this spec")
            progress(result)
            results[spec.name] = result
        return results

    monkeypatch.setattr(grade_module, "run_cases_locally", execute)
    return asked


def write(tmp_path: Path, data: dict, name: str = "sheet.yaml") -> Path:
    path = tmp_path / name
    path.write_text(yaml.safe_dump(data))
    return path


def test_grades_the_reference_sheet_and_writes_every_export(engine, tmp_path):
    out = tmp_path / "out"
    result = CliRunner().invoke(grade, [str(REFERENCE_YAML), "--out", str(out)])
    assert result.exit_code == 0, result.output
    rubric = load_rubric("L03")
    assert f"total: {rubric.max_total:g} / {rubric.max_total:g} (rubric L03 v{rubric.version}" in result.stdout
    assert "A2  credit" in result.stdout and "Evidence: N1 " in result.stdout
    # The lesson runs (N1-N4, both friction runs of the lab check, the colour control) and the sheet's two configs.
    assert "running 9 cases" in result.stderr and "sheet.table_exercise" in engine
    report = GradeReport.model_validate_json((out / "report.json").read_text())
    assert report.total == rubric.max_total and report.student == "reference"
    gradescope = json.loads((out / "results.json").read_text())
    assert gradescope["score"] == report.total and len(gradescope["tests"]) == len(rubric.items)
    assert gradescope["execution_time"] >= 0
    rows = list(csv.DictReader(io.StringIO((out / "grades.csv").read_text())))
    assert [r["student"] for r in rows] == ["reference"]


def test_json_flag_prints_only_the_report_on_stdout(engine, tmp_path):
    result = CliRunner().invoke(grade, [str(REFERENCE_YAML), "--out", str(tmp_path), "--json"])
    assert result.exit_code == 0, result.output
    report = GradeReport.model_validate_json(result.stdout)
    assert report.rubric_version == load_rubric("L03").version


def test_configs_folder_supplies_the_sheets_configs(engine, tmp_path):
    data = copy.deepcopy(REFERENCE)
    configs = data.pop("configs")
    folder = tmp_path / "configs"
    folder.mkdir()
    (folder / "table_exercise.json").write_text(json.dumps(configs["table_exercise"]))
    (folder / "extension.yaml").write_text(yaml.safe_dump(configs["extension"]))
    sheet = write(tmp_path, data)
    result = CliRunner().invoke(grade, [str(sheet), "--configs", str(folder), "--out", str(tmp_path / "out")])
    assert result.exit_code == 0, result.output
    assert GradeReport.model_validate_json((tmp_path / "out" / "report.json").read_text()).total == \
        load_rubric("L03").max_total

    both = write(tmp_path, REFERENCE, "both.yaml")
    clash = CliRunner().invoke(grade, [str(both), "--configs", str(folder), "--out", str(tmp_path / "o2")])
    assert clash.exit_code == 1 and "configs.extension: given both in" in clash.output


def test_an_invalid_sheet_is_refused_naming_each_item(engine, tmp_path):
    data = copy.deepcopy(REFERENCE)
    data["answers"]["A3"]["agree"] = "yes"
    data["answers"]["Z1"] = {}
    del data["answers"]["C2"]
    result = CliRunner().invoke(grade, [str(write(tmp_path, data)), "--out", str(tmp_path / "out")])
    assert result.exit_code == 1
    for line in ("answers.A3.agree: Input should be a valid boolean", "answers.Z1: Extra inputs are not permitted",
                 "answers.C2: Field required"):
        assert line in result.output
    assert engine == [] and not (tmp_path / "out").exists()


def test_a_two_factor_config_is_not_run_and_graded_as_such(engine, tmp_path):
    data = copy.deepcopy(REFERENCE)
    data["configs"]["table_exercise"]["initial_speed"] = 3.0
    result = CliRunner().invoke(grade, [str(write(tmp_path, data)), "--out", str(tmp_path / "out")])
    assert result.exit_code == 0, result.output
    assert "config NOT RUN: table_exercise vs friction-baseline: too many inputs changed at once" in result.stderr
    assert "initial_speed: 2.0 -> 3.0" in result.stderr
    assert "sheet.table_exercise" not in engine
    # The items comparing the table-exercise run are voided; H5's "only table friction changed" is simply wrong.
    assert "H2  one_factor_violation" in result.stdout and "H5  no_credit" in result.stdout


def test_unmeasured_cases_exit_2_and_show_not_measured(engine, tmp_path):
    data = copy.deepcopy(REFERENCE)
    data["configs"]["extension"]["substeps"] = 3  # a valid one-factor config nobody measured in this session
    result = CliRunner().invoke(grade, [str(write(tmp_path, data)), "--out", str(tmp_path / "out")])
    assert result.exit_code == 2, result.output
    assert "X2  not_measured" in result.stdout and "no recorded measurement" in result.stdout
    assert "sheet.extension: failed" in result.stderr


def test_unknown_rubric_version_is_a_clear_error(engine, tmp_path):
    result = CliRunner().invoke(grade, [str(REFERENCE_YAML), "--out", str(tmp_path),
                                        "--rubric-version", "99"])
    assert result.exit_code == 1 and "no rubric version '99'" in result.output


@pytest.mark.slow
def test_end_to_end_on_real_genesis(tmp_path):
    """No replacement: the command runs every needed case through the engine (warm mode) and grades them."""
    out = tmp_path / "out"
    result = CliRunner().invoke(grade, [str(REFERENCE_YAML), "--out", str(out), "--json"])
    assert result.exit_code == 0, result.output
    report = GradeReport.model_validate_json(result.stdout)
    assert report.complete and report.total == report.max_total == load_rubric("L03").max_total
    assert (out / "cases" / "sheet.table_exercise" / "arrays.npz").exists()
    assert report.item("H2").backends["sheet.table_exercise"] == "cpu"


def test_a_number_the_service_cannot_hold_is_refused_by_its_field_before_any_case_runs(tmp_path):
    """`grader grade` reads sheets and config files as the sheet page's import does (issue 44, 6a): no traceback."""
    sheet = tmp_path / "sheet.yaml"
    sheet.write_text(REFERENCE_YAML.read_text().replace("samples: 75", "samples: " + "9" * 5000))
    result = CliRunner().invoke(grade, [str(sheet), "--out", str(tmp_path / "out")])
    assert result.exit_code == 1, (result.output, result.exception)
    assert f"{sheet}: cannot read YAML/JSON: answers.C1.samples: a whole number may have at most 4300 digits" \
        in result.output
    configs = tmp_path / "configs"
    configs.mkdir()
    (configs / "extension.yaml").write_text("kind: contact\nname: N5\ndt: 0.01\nsubsteps: 1:00\n")
    data = copy.deepcopy(REFERENCE)
    del data["configs"]["extension"]
    base60 = CliRunner().invoke(grade, [str(write(tmp_path, data)), "--configs", str(configs),
                                        "--out", str(tmp_path / "out")])
    assert base60.exit_code == 1 and "extension.yaml: cannot read YAML/JSON: substeps: base-60 numbers" \
        in base60.output, (base60.output, base60.exception)
