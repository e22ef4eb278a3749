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
