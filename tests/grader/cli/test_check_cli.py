"""`grader check` as a user runs it: a real process, real Genesis, the lesson's final line and exit status."""

import json
import subprocess
import sys

import pytest

pytestmark = pytest.mark.slow


def grader(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "grader.cli", *args], capture_output=True, text=True, cwd=cwd,
                          timeout=900)


def test_check_passes_on_cpu_and_keeps_evidence_in_the_output_folder(tmp_path):
    """Through `grader lesson check L03` (issue 45, item 6), which validates the lesson's declaration and files, then
    runs `grader check`'s own run_check with the declared lesson's check cases and lab check."""
    done = grader("lesson", "check", "L03", "--backend", "cpu", "--mode", "warm", "--out", str(tmp_path / "check"))
    assert done.returncode == 0, done.stdout + done.stderr
    assert "texts in en, zh: no problem" in done.stdout
    assert "L03 check: 6 cases on backend=cpu, rendering=off, mode=warm" in done.stdout
    assert "L03 CHECK: PASSED" in done.stdout
    assert "[PASS] at fixed dt, the finer internal timestep reduces the penetration proxy" in done.stdout
    cases = tmp_path / "check" / "cases"
    assert sorted(p.name for p in cases.iterdir()) == sorted(
        ["N1", "N2", "N3", "N4", "friction-baseline", "friction-table-0.30"])
    assert all((cases / name / "arrays.npz").exists() for name in ("N1", "friction-baseline"))
    report = json.loads((tmp_path / "check" / "check.json").read_text())
    assert report["passed"] is True and len(report["conditions"]) == 12


def test_broken_configuration_prints_the_failed_condition_and_exits_non_zero(tmp_path):
    spec = tmp_path / "n1-no-collision.json"
    spec.write_text(json.dumps({"kind": "contact", "name": "N1", "enable_collision": False}))
    done = grader("check", "--mode", "warm", "--out", str(tmp_path / "check"), "--spec", str(spec))
    assert done.returncode == 1
    assert "L03 CHECK: FAILED" in done.stdout
    assert "failed: the cube contacts the table in every case and does not pass through it" in done.stdout


def test_invalid_override_names_the_field_and_runs_nothing(tmp_path):
    spec = tmp_path / "bad.json"
    spec.write_text(json.dumps({"kind": "contact", "name": "N2", "dt": 0.01, "duration": 1.505}))
    done = grader("check", "--out", str(tmp_path / "check"), "--spec", str(spec))
    assert done.returncode != 0
    assert "duration: duration / dt = 150.5 is not an integer number of outer steps" in done.stderr
    assert not (tmp_path / "check" / "cases").exists()


def test_case_show_prints_a_runnable_spec_and_schema_lists_the_fields():
    shown = grader("case", "show", "N4")
    assert shown.returncode == 0 and json.loads(shown.stdout)["substeps"] == 2
    derived = json.loads(grader("case", "show", "N4", "--derived").stdout)
    assert (derived["substep_dt"], derived["n_steps"], derived["internal_updates"]) == (0.01, 75, 150)
    schema = json.loads(grader("case", "schema").stdout)
    assert "ContactCase" in json.dumps(schema) and "FrictionCase" in json.dumps(schema)
    unknown = grader("case", "show", "N9")
    # the known cases are every installed lesson's (L02's S1, S2 are listed too)
    assert unknown.returncode != 0 and "known cases: " in unknown.stderr and " N1, " in unknown.stderr


def test_check_takes_an_installed_lessons_name_and_refuses_any_other(tmp_path):
    """`grader check --lesson NAME` (issue 45): the choices are the installed lessons; an unknown name runs nothing."""
    from click.testing import CliRunner

    from grader.cli.check import check

    unknown = CliRunner().invoke(check, ["--lesson", "L99", "--out", str(tmp_path / "check")])
    assert unknown.exit_code == 2 and "Invalid value for '--lesson'" in unknown.output and "'L03'" in unknown.output
    assert not (tmp_path / "check").exists()
    assert "--lesson [L02|L03]" in CliRunner().invoke(check, ["--help"]).output  # the installed lessons
