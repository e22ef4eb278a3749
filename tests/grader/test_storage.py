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
