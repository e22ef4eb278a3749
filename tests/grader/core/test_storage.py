"""Schema, settings and the reuse key: the migration matches the models, placeholders are refused in production."""

from __future__ import annotations

import pytest

from grader.core import content_key as reuse


def test_the_migration_creates_exactly_the_models(tmp_path):
    from alembic.autogenerate import compare_metadata
    from alembic.migration import MigrationContext

    from grader.core.db import make_engine, migrate
    from grader.core.models import Base

    url = f"sqlite:///{tmp_path / 'm.db'}"
    migrate(url)
    engine = make_engine(url)
    with engine.connect() as conn:
        diff = compare_metadata(MigrationContext.configure(conn), Base.metadata)
    engine.dispose()
    assert diff == []


def alembic_config(url: str):
    """Alembic's configuration for the project's migrations on `url`, to step them down and up."""
    from alembic.config import Config

    from grader.core.db import MIGRATIONS

    config = Config()
    config.set_main_option("script_location", str(MIGRATIONS))
    config.set_main_option("sqlalchemy.url", url.replace("%", "%%"))
    return config


def migrated_with_a_submission(url: str, specs: list):
    """(engine, submission id) of a database migrated to head holding one submission of alice's with these cases."""
    from sqlalchemy import select
    from sqlalchemy.orm import Session

    from grader.core.db import make_engine, migrate
    from grader.core.models import User
    from grader.services.submissions import submit as submissions
    from tests.factories import create_people, reference_sheet

    migrate(url)
    engine = make_engine(url)
    with Session(engine) as session:
        create_people(session, course="l03", other_course="other")
        alice = session.scalar(select(User).where(User.name == "alice"))
        submission = submissions.create_submission(session=session, student=alice, lesson="L03",
                                                   sheet=reference_sheet(), specs=specs, force_rerun=False)
        session.commit()
        return engine, submission.id


def down_to_0005_and_up(url: str) -> None:
    """Migrations 0008-0006 go down, taking their columns, and up again; an existing course shows UTC after."""
    from alembic import command
    from sqlalchemy import inspect, text

    from grader.core.db import make_engine, migrate

    migrate(url)
    engine = make_engine(url)
    with engine.begin() as conn:
        conn.execute(text("INSERT INTO courses (name, created_at, timezone) "
                          "VALUES ('c', CURRENT_TIMESTAMP, 'Europe/Berlin')"))
    config = alembic_config(url)
    command.downgrade(config, "0005")
    with engine.connect() as conn:
        columns = {c["name"] for table in ("assignments", "courses") for c in inspect(conn).get_columns(table)}
    assert not columns & {"item_visibility", "max_per_hour", "timezone"} and "visibility" in columns
    command.upgrade(config, "head")
    with engine.connect() as conn:
        assert conn.execute(text("SELECT timezone FROM courses WHERE name = 'c'")).scalar() == "UTC"
    engine.dispose()


def test_migrations_0006_to_0008_go_down_and_up(tmp_path):
    down_to_0005_and_up(f"sqlite:///{tmp_path / 'm.db'}")


def test_migration_0009_makes_every_grade_stored_before_it_complete(tmp_path):
    """Grades stored before 0009 had their figures and lab check drawn before they were stored: complete, as of
    when they were made. One stored after it by a worker still drawing stays incomplete."""
    from alembic import command
    from sqlalchemy import select, text
    from sqlalchemy.orm import Session

    from grader.core.models import Grade

    url = f"sqlite:///{tmp_path / 'm.db'}"
    engine, submission_id = migrated_with_a_submission(url, specs=[])
    with Session(engine) as session:
        session.add(Grade(submission_id=submission_id, rubric_lesson="L03", rubric_version="2", rubric_hash="x",
                          total=1, max_total=2, report={}))
        session.commit()
    config = alembic_config(url)
    command.downgrade(config, "0008")
    command.upgrade(config, "head")
    with engine.connect() as conn:
        created, completed = conn.execute(text("SELECT created_at, completed_at FROM grades")).one()
    assert completed is not None and completed == created
    with Session(engine) as session:
        session.get(Grade, 1).superseded_at = session.get(Grade, 1).created_at
        session.flush()
        session.add(Grade(submission_id=submission_id, rubric_lesson="L03", rubric_version="3", rubric_hash="y",
                          total=1, max_total=2, report={}, completed_at=None))
        session.commit()
        assert session.scalar(select(Grade.completed_at).where(Grade.id == 2)) is None
    engine.dispose()


def test_migration_0010_renames_a_case_runs_attempt_to_delivery_keeping_its_number(tmp_path):
    """A case run's message number was called attempt, like a student's attempt on an assignment; 0010 renames the
    column and every stored number stays, down and up."""
    from alembic import command
    from sqlalchemy import inspect, text

    from rubric import get_case

    url = f"sqlite:///{tmp_path / 'm.db'}"
    engine, _ = migrated_with_a_submission(url, specs=[get_case("N1"), get_case("N2")])
    with engine.begin() as conn:
        conn.execute(text("UPDATE case_runs SET delivery = 3 WHERE name = 'N2'"))
    config = alembic_config(url)
    command.downgrade(config, "0009")
    with engine.connect() as conn:
        assert "delivery" not in {c["name"] for c in inspect(conn).get_columns("case_runs")}
        assert dict(conn.execute(text("SELECT name, attempt FROM case_runs")).all()) == {"N1": 1, "N2": 3}
    command.upgrade(config, "head")
    with engine.connect() as conn:
        assert "attempt" not in {c["name"] for c in inspect(conn).get_columns("case_runs")}
        assert dict(conn.execute(text("SELECT name, delivery FROM case_runs")).all()) == {"N1": 1, "N2": 3}
    engine.dispose()


def test_migration_0011_renames_an_assignments_items_to_part_keeping_it(tmp_path):
    """An assignment's part of the sheet (checkpoints, exercises, sheet) was a column named items; it stays, down and
    up."""
    from alembic import command
    from sqlalchemy import text

    from grader.core.db import make_engine, migrate

    url = f"sqlite:///{tmp_path / 'm.db'}"
    migrate(url)
    engine = make_engine(url)
    with engine.begin() as conn:
        conn.execute(text("INSERT INTO courses (name, created_at, timezone) VALUES ('c', CURRENT_TIMESTAMP, 'UTC')"))
        conn.execute(text("INSERT INTO users (course_id, name, role, created_at) VALUES (1, 'p', 'instructor', "
                          "CURRENT_TIMESTAMP)"))
        conn.execute(text(
            "INSERT INTO assignments (course_id, title, lesson, part, open_at, due_at, hard_close_at, "
            "late_penalty_per_day, counted_attempt, visibility, item_visibility, created_by_id, created_at) VALUES "
            "(1, 'CP', 'L03', 'checkpoints', CURRENT_TIMESTAMP, CURRENT_TIMESTAMP, CURRENT_TIMESTAMP, 0, 'latest', "
            "'immediate', '{}', 1, CURRENT_TIMESTAMP)"))
    config = alembic_config(url)
    command.downgrade(config, "0010")
    with engine.connect() as conn:
        assert conn.execute(text("SELECT items FROM assignments")).scalar() == "checkpoints"
    command.upgrade(config, "head")
    with engine.connect() as conn:
        assert conn.execute(text("SELECT part FROM assignments")).scalar() == "checkpoints"
    engine.dispose()


def test_migration_0023_renames_the_figures_event_state_completing_and_back(tmp_path):
    """The reconciler's re-send of a grade's completion was logged as state "figures" though nothing is drawn; 0023
    renames every stored one "completing", keeping its detail and leaving every other state, down and up."""
    from alembic import command
    from sqlalchemy import text

    url = f"sqlite:///{tmp_path / 'm.db'}"
    engine, submission_id = migrated_with_a_submission(url, specs=[])
    config = alembic_config(url)
    command.downgrade(config, "0022")
    re_sent = "grade task re-sent: the grade is stored, its figures and lab check are not"
    with engine.begin() as conn:
        for state, detail in (("figures", re_sent), ("lab-check", "lab check stored")):
            conn.execute(text("INSERT INTO events (submission_id, state, detail, at) VALUES (:s, :state, :detail, "
                              "CURRENT_TIMESTAMP)"), {"s": submission_id, "state": state, "detail": detail})

    def states() -> list[tuple[str, str]]:
        with engine.connect() as conn:
            return [tuple(row) for row in conn.execute(text("SELECT state, detail FROM events ORDER BY id"))]

    command.upgrade(config, "head")
    upgraded = states()
    assert ("completing", re_sent) in upgraded and ("lab-check", "lab check stored") in upgraded
    assert "figures" not in {state for state, _ in upgraded}
    assert ("submitted", "0 case runs") in upgraded
    command.downgrade(config, "0022")
    assert states() == [("figures", re_sent) if row == ("completing", re_sent) else row for row in upgraded]
    command.upgrade(config, "head")
    assert states() == upgraded
    engine.dispose()


def test_production_refuses_embedded_and_placeholder_urls():
    from grader.core.settings import Settings

    with pytest.raises(ValueError, match="database_url"):
        Settings(environment="production", broker_url="redis://r:6379/0")
    with pytest.raises(ValueError, match="database_url"):
        Settings(environment="production", database_url="postgresql://grader:changeme@db/grader",
                 broker_url="redis://r:6379/0")
    ok = Settings(environment="production", database_url="postgresql://grader:s3cr3t-9f@db/grader",
                  broker_url="redis://r:6379/0")
    assert ok.database_url.startswith("postgresql")


def test_the_reuse_key_covers_spec_backend_precision_versions_and_runner(monkeypatch):
    from rubric import get_case

    spec = get_case("N1").model_dump(mode="json", exclude_computed_fields=True)
    base = reuse.content_key(reuse.key_inputs(spec, backend="cpu", precision="32"))
    assert base == reuse.content_key(reuse.key_inputs(dict(spec), backend="cpu", precision="32"))
    changed = {**spec, "substeps": 2}
    assert reuse.content_key(reuse.key_inputs(changed, backend="cpu", precision="32")) != base
    assert reuse.content_key(reuse.key_inputs(spec, backend="rocm", precision="32")) != base
    assert reuse.content_key(reuse.key_inputs(spec, backend="cpu", precision="64")) != base
    inputs = reuse.key_inputs(spec, backend="cpu", precision="32")
    assert set(inputs["versions"]) == {"genesis-world", "quadrants", "torch"}
    assert reuse.content_key({**inputs, "versions": {**inputs["versions"], "torch": "9.9"}}) != base
    assert reuse.content_key({**inputs, "runner_version": "999"}) != base


def test_migration_0024_adds_variant_pools_and_leaves_every_earlier_submission_on_the_shipped_cases(tmp_path):
    """0024 adds the pool tables and a nullable submissions.variant_id: a submission stored before keeps NULL (graded
    on the lesson's shipped cases as before); one variant per (assignment, student) is enforced by the database; down
    to 0023 drops the tables and the column and keeps the submission, and up again."""
    from alembic import command
    from sqlalchemy import inspect, text
    from sqlalchemy.exc import IntegrityError

    url = f"sqlite:///{tmp_path / 'm.db'}"
    engine, submission_id = migrated_with_a_submission(url, specs=[])
    config = alembic_config(url)
    command.downgrade(config, "0023")
    with engine.connect() as conn:
        tables = set(inspect(conn).get_table_names())
        columns = {c["name"] for c in inspect(conn).get_columns("submissions")}
    assert not tables & {"variant_pools", "pool_variants", "student_variants", "copy_flags"}
    assert "variant_id" not in columns
    command.upgrade(config, "head")
    with engine.begin() as conn:
        assert conn.execute(text("SELECT variant_id FROM submissions WHERE id = :i"),
                            {"i": submission_id}).one() == (None,)
        people = dict(conn.execute(text("SELECT name, id FROM users")).all())
        course = conn.execute(text("SELECT course_id FROM users WHERE name = 'prof'")).scalar()
        conn.execute(text(
            "INSERT INTO assignments (course_id, title, lesson, part, open_at, due_at, hard_close_at, "
            "late_penalty_per_day, counted_attempt, visibility, item_visibility, created_by_id, created_at) VALUES "
            "(:c, 'a', 'L03', 'sheet', CURRENT_TIMESTAMP, CURRENT_TIMESTAMP, CURRENT_TIMESTAMP, 0, 'latest', "
            "'immediate', '{}', :p, CURRENT_TIMESTAMP)"), {"c": course, "p": people["prof"]})
        assignment = conn.execute(text("SELECT id FROM assignments")).scalar()
        conn.execute(text(
            "INSERT INTO variant_pools (assignment_id, lesson, space_version, space_hash, rubric_version, seed, k, "
            "state, rejected, created_by_id, created_at) VALUES (:a, 'L03', '1', 'h', '2', 7, 1, 'measuring', '[]', "
            ":p, CURRENT_TIMESTAMP)"), {"a": assignment, "p": people["prof"]})
        pool = conn.execute(text("SELECT id FROM variant_pools")).scalar()
        conn.execute(text("INSERT INTO pool_variants (pool_id, name, position, parameters, digest, state) VALUES "
                          "(:p, 'v7-1', 1, '{}', 'd', 'kept')"), {"p": pool})
        variant = conn.execute(text("SELECT id FROM pool_variants")).scalar()
        conn.execute(text("INSERT INTO student_variants (assignment_id, student_id, variant_id, assigned_at) VALUES "
                          "(:a, :s, :v, CURRENT_TIMESTAMP)"), {"a": assignment, "s": people["alice"], "v": variant})
    with pytest.raises(IntegrityError), engine.begin() as conn:
        conn.execute(text("INSERT INTO student_variants (assignment_id, student_id, variant_id, assigned_at) VALUES "
                          "(:a, :s, :v, CURRENT_TIMESTAMP)"), {"a": assignment, "s": people["alice"], "v": variant})
    command.downgrade(config, "0023")
    with engine.connect() as conn:
        assert conn.execute(text("SELECT count(*) FROM submissions")).scalar() == 1
    command.upgrade(config, "head")
    engine.dispose()
