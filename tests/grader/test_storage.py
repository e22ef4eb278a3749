"""Schema, settings and the reuse key: the migration matches the models, placeholders are refused in production."""

from __future__ import annotations

import pytest

from worker import reuse


def test_the_migration_creates_exactly_the_models(tmp_path):
    from alembic.autogenerate import compare_metadata
    from alembic.migration import MigrationContext

    from grader.core.db import make_engine, migrate
    from grader.models import Base

    url = f"sqlite:///{tmp_path / 'm.db'}"
    migrate(url)
    engine = make_engine(url)
    with engine.connect() as conn:
        diff = compare_metadata(MigrationContext.configure(conn), Base.metadata)
    engine.dispose()
    assert diff == []


def down_to_0005_and_up(url: str) -> None:
    """Migrations 0008-0006 go down, taking their columns, and up again; an existing course shows UTC after."""
    from alembic import command
    from alembic.config import Config
    from sqlalchemy import inspect, text

    from grader.core.db import MIGRATIONS, make_engine, migrate

    migrate(url)
    engine = make_engine(url)
    with engine.begin() as conn:
        conn.execute(text("INSERT INTO courses (name, created_at, timezone) "
                          "VALUES ('c', CURRENT_TIMESTAMP, 'Europe/Berlin')"))
    config = Config()
    config.set_main_option("script_location", str(MIGRATIONS))
    config.set_main_option("sqlalchemy.url", url.replace("%", "%%"))
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


def test_production_refuses_embedded_and_placeholder_urls():
    from grader.settings import Settings

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
