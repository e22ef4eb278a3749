"""`grader assignment release|extend|grades` and `grader roster import --tokens-out`, over the in-process app."""

from __future__ import annotations

import stat

from grader.client import Client
from tests.grader.services.setup.test_assignments import ROSTER, at, create, submit
from tests.grader.services.setup.test_assignments import lesson_cases_stored  # noqa: F401 - autouse: the lesson measured


def client_on(url, token):
    """The CLI's client, talking to the in-process app."""
    from fastapi.testclient import TestClient

    from grader.main import app

    c = Client(url, token)  # this module's name for the class, whatever a test patches in grader.client
    c.http = TestClient(app, base_url="http://testserver/v1", headers={"Authorization": f"Bearer {token}"})
    return c


def run(api, monkeypatch, *args, who="prof"):
    from click.testing import CliRunner

    from grader.cli import assignment, main, roster

    monkeypatch.setattr(assignment, "_client", client_on)
    monkeypatch.setattr(roster, "_client", client_on)
    return CliRunner().invoke(main, [*args, "--token", api.tokens[who]])


def test_create_with_item_visibility_and_an_hourly_limit(api, monkeypatch):
    made = run(api, monkeypatch, "assignment", "create", "l03", "--title", "CP", "--part", "checkpoints",
               "--open", at(-1), "--due", at(1), "--close", at(2), "--visibility", "after_due",
               "--item-visibility", "C2=immediate", "--item-visibility", "C3=on_release", "--max-per-hour", "4")
    assert made.exit_code == 0, made.output
    assert "shown C2 immediate, C3 on_release; the other items after_due" in made.output
    row = api.client.get("/v1/assignments/1", headers=api.as_("prof")).json()
    assert (row["max_per_hour"], row["item_visibility"]) == (4, {"C2": "immediate", "C3": "on_release"})
    bad = run(api, monkeypatch, "assignment", "create", "l03", "--title", "CP", "--open", at(-1), "--due", at(1),
              "--close", at(2), "--item-visibility", "C3=later")
    assert bad.exit_code != 0 and "--item-visibility" in bad.output and "ITEM=WHEN" in bad.output
    stranger = run(api, monkeypatch, "assignment", "create", "l03", "--title", "CP", "--part", "checkpoints",
                   "--open", at(-1), "--due", at(1), "--close", at(2), "--item-visibility", "A1=on_release")
    assert stranger.exit_code != 0 and "item_visibility.A1: not an item of this assignment" in stranger.output


def test_release_extend_and_grades(api, monkeypatch, tmp_path):
    aid = create(api, due_at=at(hours=-2), hard_close_at=at(hours=-1), late_penalty_per_day=0.1,
                 visibility="on_release").json()["id"]
    extended = run(api, monkeypatch, "assignment", "extend", str(aid), "alice", "--due", at(hours=-2),
                   "--close", at(1))
    assert extended.exit_code == 0 and "alice: due" in extended.output and "granted by prof" in extended.output
    assert submit(api, aid).status_code == 202
    table = run(api, monkeypatch, "assignment", "grades", str(aid))
    assert table.exit_code == 0, table.output
    assert table.output.splitlines()[1].split()[:5] == ["alice", "7.2", "8", "10%", "1"]
    out = tmp_path / "grades.csv"
    written = run(api, monkeypatch, "assignment", "grades", str(aid), "--csv", str(out))
    assert written.exit_code == 0 and "1 students written" in written.output
    assert out.read_text().splitlines()[1].startswith("alice,7.2,8,8,0.1,")
    released = run(api, monkeypatch, "assignment", "release", str(aid))
    assert released.exit_code == 0 and "released at 20" in released.output
    refused = run(api, monkeypatch, "assignment", "grades", str(aid), who="alice")
    assert refused.exit_code != 0 and "HTTP 403" in refused.output


def test_roster_import_writes_new_tokens_to_a_private_file_once(api, monkeypatch, tmp_path):
    roster_csv = tmp_path / "roster.csv"
    roster_csv.write_text(ROSTER)
    tokens = tmp_path / "tokens.csv"
    first = run(api, monkeypatch, "roster", "import", "l03", str(roster_csv), "--tokens-out", str(tokens))
    assert first.exit_code == 0, first.output
    assert stat.S_IMODE(tokens.stat().st_mode) == 0o600
    lines = tokens.read_text().splitlines()
    assert lines[0] == "student_id,token" and [line.split(",")[0] for line in lines[1:]] == ["s1001", "s1002"]
    assert lines[1].split(",")[1] not in first.output  # the tokens go to the file only
    ada = {"Authorization": f"Bearer {lines[1].split(',')[1]}"}
    assert api.client.get("/v1/courses/l03", headers=ada).status_code == 200
    roster_csv.write_text(ROSTER + "s1003,Grace Hopper,grace@example.edu\n")
    again_file = tmp_path / "tokens2.csv"
    again = run(api, monkeypatch, "roster", "import", "l03", str(roster_csv), "--tokens-out", str(again_file))
    assert again.exit_code == 0 and "1 new students, 2 updated" in again.output
    assert [line.split(",")[0] for line in again_file.read_text().splitlines()[1:]] == ["s1003"]
    # An existing file is never written over, and nothing is imported then.
    roster_csv.write_text(ROSTER + "s1004,Edsger Dijkstra,ewd@example.edu\n")
    kept = run(api, monkeypatch, "roster", "import", "l03", str(roster_csv), "--tokens-out", str(tokens))
    assert kept.exit_code != 0 and "exists" in kept.output and tokens.read_text().splitlines() == lines
    # A refused import leaves no token file behind.
    roster_csv.write_text("student_id,name,email\nbad id,A,a@x.org\n")
    bad = run(api, monkeypatch, "roster", "import", "l03", str(roster_csv), "--tokens-out", str(tmp_path / "t3"))
    assert bad.exit_code != 0 and "csv.line 2.student_id" in bad.output and not (tmp_path / "t3").exists()
    # Without --tokens-out a new student's token is printed, once; students already there never get theirs again.
    roster_csv.write_text(ROSTER + "s1005,Barbara Liskov,bl@example.edu\n")
    printed = run(api, monkeypatch, "roster", "import", "l03", str(roster_csv))
    assert printed.exit_code == 0, printed.output
    lines = {line.split()[0]: line for line in printed.output.splitlines()[:-1]}
    assert "token " in lines["s1005"] and "token" not in lines["s1001"] and "token" not in lines["s1002"]


def test_a_student_submits_to_an_assignment_and_sees_the_withheld_items_pending(api, monkeypatch, tmp_path):
    import yaml

    from grader import client as client_module
    from grader.core.settings import settings
    from tests.grader.services.setup.test_assignments import checkpoint_sheet

    monkeypatch.setattr(client_module, "Client", client_on)
    monkeypatch.setattr(settings, "data_dir", tmp_path)
    aid = create(api, due_at=at(hours=-2), hard_close_at=at(1), item_visibility={"C3": "on_release"}).json()["id"]
    sheet = tmp_path / "sheet.yaml"
    sheet.write_text(yaml.safe_dump(checkpoint_sheet()))
    done = run(api, monkeypatch, "submit", str(sheet), "--assignment", str(aid), who="alice")
    assert done.exit_code == 0, done.output
    assert "assignment 1, attempt 1, 2 h late (1 day charged)" in done.output
    assert "graded at once, no case run (7 stored measurements of the lesson's own cases reused)" in done.output
    assert "measuring " not in done.output and "queued" not in done.output
    lines = {line.split()[0]: line for line in done.output.splitlines() if line.startswith("  C")}
    assert "pending" in lines["C3"] and "withheld: shown once “" in lines["C3"]
    assert "1 of 8 points pending (C3)" in done.output
