"""A case run's evidence lives in the database: once the worker stored a run, its artifacts folder may be lost and the
grade, the lab check, the charts' series, a regrade and every evidence download still work. Real Genesis results (the
session's `measured` cases) go through the worker's own path (`process_case_run`, `store_result`) with the case
process replaced by those recorded results; the real app in-process on SQLite, and on PostgreSQL."""

from __future__ import annotations

import dataclasses
import shutil
from pathlib import Path

import pytest
from sqlalchemy import func, select, text

import rubric
from tests import services
from tests.factories import reference_sheet, rubric_v3, sheet_results
from tests.grader.conftest import app_on


def recorded_case_process(measured: dict):
    """A `run_case` that answers with the session's real result of the case, its folder copied to where the worker
    asked, as a case process leaves it there."""
    results = sheet_results(measured)

    def run_case(spec, out_dir: Path, **_):
        result = results[spec.name]
        shutil.copytree(result.out_dir, out_dir, dirs_exist_ok=True)
        return dataclasses.replace(result, spec=spec, out_dir=str(out_dir))

    return run_case


def run_every_sent_case(api, measured) -> None:
    from grader.core.db import new_session
    from worker.case_run import process_case_run

    for case_run_id, delivery, _backend in api.sent:
        with new_session() as session:
            process_case_run(session=session, case_run_id=case_run_id, delivery=delivery,
                             run_case=recorded_case_process(measured))


def evidence_rows() -> int:
    from grader.core.db import new_session
    from grader.core.models import CaseEvidence

    with new_session() as session:
        return session.scalar(select(func.count()).select_from(CaseEvidence))


def stored_bytes() -> dict[str, int]:
    """Bytes each run's evidence row takes in the database, by case: PostgreSQL's stored (TOAST-compressed) size of
    the row, SQLite's byte length of its columns."""
    from grader.core.db import new_session

    with new_session() as session:
        if session.get_bind().dialect.name == "postgresql":
            query = "SELECT r.name, pg_column_size(e.*) FROM case_evidence e JOIN case_runs r ON r.id = e.case_run_id"
        else:
            query = ("SELECT r.name, length(e.arrays) + length(e.spec) + coalesce(length(e.provenance), 0) + "
                     "coalesce(length(e.metrics), 0) + length(e.stdout) + length(e.stderr) + length(e.sizes) "
                     "FROM case_evidence e JOIN case_runs r ON r.id = e.case_run_id")
        return dict(session.execute(text(query)).all())


def graded_after_the_folder_is_lost(api, measured) -> None:
    from grader.core.db import new_session
    from grader.core.models import Event, Submission
    from grader.core.settings import settings
    from worker.grading import complete_grade, grade_submission

    response = api.client.post("/v1/submissions", json={"sheet": reference_sheet()}, headers=api.as_("alice"))
    assert response.status_code == 202, response.text
    sid = response.json()["id"]
    assert len(api.sent) == 9
    run_every_sent_case(api, measured)
    written = {}  # what the worker's case processes wrote, read before the folder goes
    with new_session() as session:
        submission = session.get(Submission, sid)
        assert submission.status == "grading"
        for run in submission.case_runs:
            folder = Path(run.artifact_dir)
            assert folder.is_relative_to(settings.artifacts_dir)
            written[run.name] = {f: (folder / f).read_bytes() for f in ("arrays.npz", "stdout.txt", "stderr.txt")}
    assert evidence_rows() == 9
    sizes = stored_bytes()
    print(f"evidence bytes stored per case: {sizes}; mean {sum(sizes.values()) / len(sizes):.0f}")
    assert all(size < 100_000 for size in sizes.values()), sizes

    shutil.rmtree(settings.artifacts_dir)  # the worker's host loses its disk
    with new_session() as session:
        grade = grade_submission(session=session, submission_id=sid)
        assert grade is not None, session.scalars(select(Event.detail).where(Event.submission_id == sid)
                                                  .order_by(Event.id.desc())).first()
        # The same score as the session's results give straight from memory: every array was read back whole.
        expected = rubric.grade_sheet(rubric.parse_sheet(reference_sheet(), "sheet"), sheet_results(measured),
                                      rubric.load_rubric("L03", grade.rubric_version))
        assert grade.total == expected.total > 0
        total = grade.total
    with new_session() as session:
        grade = complete_grade(session=session, submission_id=sid)
        outputs = next(c for c in grade.report["check"]["conditions"] if c["id"] == "outputs")
        assert outputs["passed"] and "kept in the database" in outputs["evidence"], outputs
    assert not settings.artifacts_dir.exists()  # completing the grade wrote nothing to a disk (no figure files)

    state = api.client.get(f"/v1/submissions/{sid}", headers=api.as_("alice")).json()
    assert state["status"] == "graded" and state["total"] == total
    for name, files in written.items():
        for filename, body in files.items():
            got = api.client.get(f"/v1/submissions/{sid}/case-runs/{name}/files/{filename}", headers=api.as_("alice"))
            assert got.status_code == 200 and got.content == body, (name, filename, got.status_code)
        spec = api.client.get(f"/v1/submissions/{sid}/case-runs/{name}/files/spec.json", headers=api.as_("prof"))
        assert spec.status_code == 200 and spec.json()["name"] == name
    page = api.client.get(f"/submissions/{sid}", headers=api.as_("prof")).text
    assert f'href="/submissions/{sid}/case-runs/N1/arrays.npz"' in page
    html = api.client.get(f"/submissions/{sid}/case-runs/N1/arrays.npz", headers=api.as_("prof"))
    assert html.status_code == 200 and html.content == written["N1"]["arrays.npz"]

    published = api.client.post("/v1/rubrics/versions", json=rubric_v3(high_lane_unchanged=0.001),
                                headers=api.as_("prof"))
    assert published.status_code == 201, published.text
    regrade = api.client.post("/v1/courses/l03/regrades", headers=api.as_("prof"),
                              json={"version": "3", "content_hash": published.json()["content_hash"]})
    assert regrade.status_code == 201 and regrade.json()["regraded"] == 1, regrade.text

    # Bob's identical sheet reuses every stored measurement: his runs read alice's rows, none is copied.
    response = api.client.post("/v1/submissions", json={"sheet": reference_sheet()}, headers=api.as_("bob"))
    assert response.status_code == 202 and response.json()["status"] == "grading", response.text
    bob = response.json()["id"]
    with new_session() as session:
        assert grade_submission(session=session, submission_id=bob) is not None
    assert evidence_rows() == 9
    got = api.client.get(f"/v1/submissions/{bob}/case-runs/N3/files/arrays.npz", headers=api.as_("bob"))
    assert got.status_code == 200 and got.content == written["N3"]["arrays.npz"]


def test_grade_regrade_and_downloads_work_after_the_workers_folder_is_deleted(api, measured):
    graded_after_the_folder_is_lost(api, measured)


@pytest.fixture
def pg_api(tmp_path, monkeypatch):
    """The `api` fixture of tests/grader on a fresh PostgreSQL database (evidence as bytea)."""
    with services.postgres_database() as url, app_on(url, tmp_path, monkeypatch) as state:
        yield state


@pytest.mark.integration
def test_on_postgresql_too(pg_api, measured):
    graded_after_the_folder_is_lost(pg_api, measured)


def test_migration_0017_moves_existing_folders_in_and_records_the_missing_ones(tmp_path, measured):
    """Runs stored before 0017 kept only their folder's path: the upgrade copies what each folder holds into
    case_evidence (the .npz byte for byte) and leaves an event on a run whose folder is gone."""
    from alembic import command
    from alembic.script import ScriptDirectory
    from sqlalchemy import text

    from rubric import get_case
    from tests.grader.core.test_storage import alembic_config, migrated_with_a_submission

    url = f"sqlite:///{tmp_path / 'm.db'}"
    engine, _ = migrated_with_a_submission(url, specs=[get_case("N1"), get_case("N2")])
    config = alembic_config(url)
    command.downgrade(config, ScriptDirectory.from_config(config).get_revision("0017").down_revision)
    kept = tmp_path / "artifacts" / "N1"
    shutil.copytree(measured["N1"].out_dir, kept)
    with engine.begin() as conn:
        conn.execute(text("UPDATE case_runs SET status = 'done', result_status = 'ok', artifact_dir = :d "
                          "WHERE name = 'N1'"), {"d": str(kept)})
        conn.execute(text("UPDATE case_runs SET status = 'failed', result_status = 'failed', artifact_dir = :d "
                          "WHERE name = 'N2'"), {"d": str(tmp_path / "gone")})
    command.upgrade(config, "head")
    with engine.connect() as conn:
        rows = conn.execute(text("SELECT r.name, e.arrays, e.stdout, e.sizes FROM case_evidence e "
                                 "JOIN case_runs r ON r.id = e.case_run_id")).all()
        events = conn.execute(text("SELECT r.name, v.detail FROM events v JOIN case_runs r ON r.id = v.case_run_id "
                                   "WHERE v.state = 'evidence'")).all()
    engine.dispose()
    assert [r.name for r in rows] == ["N1"]
    assert rows[0].arrays == (kept / "arrays.npz").read_bytes() and rows[0].stdout == (kept / "stdout.txt").read_text()
    assert [(name, str(tmp_path / "gone") in detail and "missing" in detail)
            for name, detail in events] == [("N2", True)]
