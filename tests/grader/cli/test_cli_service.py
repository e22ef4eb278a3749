"""`grader admin` commands on a real SQLite database: migrate, then a token that the API accepts."""

from __future__ import annotations

from click.testing import CliRunner


def test_admin_token_creates_course_user_and_a_working_token(api):
    from grader.cli.service import admin

    runner = CliRunner()
    result = runner.invoke(admin, ["token", "l03", "carol", "--role", "student"])
    assert result.exit_code == 0, result.output
    token = result.output.strip()
    response = api.client.get("/v1/submissions", headers={"Authorization": f"Bearer {token}"})
    assert response.status_code == 200 and response.json() == []
    clash = runner.invoke(admin, ["token", "l03", "carol", "--role", "instructor"])
    assert clash.exit_code != 0 and "already exists" in clash.output


def test_submit_refuses_a_number_the_service_cannot_hold_by_its_field_and_sends_nothing(tmp_path):
    """`grader submit` reads a YAML or JSON sheet as the sheet page's import does (issue 44, 6a): no traceback."""
    import json

    from grader.cli.service import submit
    from tests.factories import REFERENCE_YAML, reference_sheet

    files = {"sheet.yaml": REFERENCE_YAML.read_text().replace("samples: 75", "samples: " + "9" * 5000),
             "sheet.json": json.dumps(reference_sheet()).replace('"samples": 75', '"samples": ' + "9" * 5000),
             "base60.yaml": REFERENCE_YAML.read_text().replace("substeps: 4", "substeps: 1:59:59")}
    for name, text in files.items():
        path = tmp_path / name
        path.write_text(text)
        # Nothing listens on port 9: had the sheet been sent, the error would be the connection's.
        result = CliRunner().invoke(submit, [str(path), "--token", "t", "--url", "http://127.0.0.1:9"])
        field, rule = (("configs.extension.substeps", "base-60 numbers such as 1:59:59") if name == "base60.yaml"
                       else ("answers.C1.samples", "a whole number may have at most 4300 digits, this one has 5000"))
        assert result.exit_code == 1 and f"{path}: {field}: {rule}" in result.output, (name, result.output[-500:],
                                                                                       result.exception)
