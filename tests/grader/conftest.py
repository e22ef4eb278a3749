"""The real app in-process (FastAPI TestClient) on a fresh SQLite database; enqueueing is recorded, not sent."""

from __future__ import annotations

import shutil
import sqlite3
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path

import pytest

from tests.factories import create_people


@dataclass
class Api:
    client: object
    tokens: dict[str, str]
    sent: list = field(default_factory=list)
    priorities: list = field(default_factory=list)  # the priority each sent case run was given, in sending order

    def as_(self, who: str) -> dict[str, str]:
        return {"Authorization": f"Bearer {self.tokens[who]}"}

    def send_case_run(self, *args, priority=None) -> None:
        """Stands for grader.dispatch.send_case_run: records what would be sent, and at which priority."""
        self.sent.append(args)
        self.priorities.append(priority)


_TEMPLATES: dict[str, Path] = {}


def migrated(url: str) -> None:
    """The database at `url` at the newest revision. A SQLite file is a copy of one migrated once per test process
    (0.4 ms against ~2 s for the 22 migrations, run by ~560 tests); a server's database is migrated as it is.
    tests/grader/test_storage.py migrates for real, step by step, and compares the schema with the tables."""
    from grader.core import db

    prefix = "sqlite:///"
    if not url.startswith(prefix) or ":memory:" in url:
        db.migrate(url)
        return
    heads = _TEMPLATES.get("head")
    if heads is None:
        folder = Path(tempfile.mkdtemp(prefix="grader-migrated-"))
        heads = folder / "template.db"
        db.migrate(prefix + str(heads))
        with sqlite3.connect(heads) as conn:  # one self-contained file: the WAL folded in, no -wal/-shm to copy
            conn.execute("PRAGMA wal_checkpoint(TRUNCATE)")
            conn.execute("PRAGMA journal_mode=DELETE")
        _TEMPLATES["head"] = heads
    target = Path(url[len(prefix):])
    target.parent.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(heads, target)


@contextmanager
def app_on(url: str, tmp_path, monkeypatch) -> Iterator[Api]:
    """The app in-process on the database at `url` (migrated, people created), enqueueing recorded."""
    from fastapi.testclient import TestClient
    from sqlalchemy.orm import Session

    from grader import dispatch
    from grader.core import db
    from grader.main import app
    from grader.services.identity import quotas
    from grader.core.settings import settings

    monkeypatch.setattr(settings, "database_url", url)
    monkeypatch.setattr(settings, "artifacts_dir", tmp_path / "artifacts")
    monkeypatch.setattr(db, "_engine", None)
    migrated(url)
    with Session(db.get_engine()) as session:
        tokens = create_people(session, course="l03", other_course="other")
        session.commit()
    quotas._limiter.cache_clear()  # a fresh count per test: user ids repeat across the tests' databases
    state = Api(client=TestClient(app), tokens=tokens)
    monkeypatch.setattr(dispatch, "send_case_run", state.send_case_run)
    try:
        yield state
    finally:
        db.get_engine().dispose()
        db._engine = None


@pytest.fixture
def api(tmp_path, monkeypatch):
    with app_on(f"sqlite:///{tmp_path / 'grader.db'}", tmp_path, monkeypatch) as state:
        yield state


@pytest.fixture
def lesson_measured(api, measured) -> dict[str, int]:
    """The lesson's own cases, really measured (the session's `measured` runs), stored as done for a submission of
    another course's instructor: the lesson's cases are the same for every course and student, so a checkpoint sheet
    is graded at once on them. Their case run ids by name."""
    from grader.core.db import new_session
    from tests.factories import store_lesson_runs

    with new_session() as session:
        return store_lesson_runs(session, measured, by="eve")
