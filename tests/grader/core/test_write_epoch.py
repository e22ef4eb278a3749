"""The write epoch (grader.core.freshness, hooked under every engine by grader.core.db): changed after each commit that
wrote anything, ORM flushes and bulk statements alike, and only once the commit is done; not by a read, a rolled-back
write, or a page session merely noted as seen again. On the embedded store and on a real Redis."""

from __future__ import annotations

import uuid
from datetime import timedelta

import pytest
from sqlalchemy import select, text, update
from sqlalchemy.orm import Session


@pytest.fixture(params=["embedded", "redis"])
def engine(request, tmp_path, monkeypatch):
    from grader.core import db, freshness
    from grader.core.settings import settings
    from tests.factories import create_people
    from tests.grader.conftest import migrated

    if request.param == "redis":
        from tests.services import REDIS_URL, redis_client

        redis_client()
        monkeypatch.setattr(settings, "broker_url", REDIS_URL)
    else:
        monkeypatch.setattr(settings, "broker_url", "filesystem://")
        monkeypatch.setattr(settings, "data_dir", tmp_path / "data")
    monkeypatch.setattr(freshness, "PREFIX", f"grader:fresh-test-{uuid.uuid4().hex[:12]}:")
    freshness._owed.clear()  # nothing owed or resting from another test's store
    freshness._failed_at[0] = float("-inf")
    url = f"sqlite:///{tmp_path / 'grader.db'}"
    migrated(url)
    engine = db.make_engine(url)
    with Session(engine) as session:
        create_people(session, course="l03", other_course="other")
        session.commit()
    yield engine
    engine.dispose()
    freshness._owed.clear()
    freshness._failed_at[0] = float("-inf")


def epoch():
    from grader.core import freshness

    value = freshness.read_epoch()
    assert value is not None
    return value


def test_a_commit_that_wrote_changes_the_epoch_once_it_is_done(engine):
    from grader.core.models import User, WebSession, utcnow
    from grader.services.identity import sessions

    before = epoch()
    with Session(engine) as session:
        user = session.scalars(select(User)).first()
        sessions.open_session(session=session, user=user)
        session.flush()
        assert epoch() == before  # written, not committed: readers still see the old rows
        session.commit()
    after = epoch()
    assert after != before
    with Session(engine) as session:  # a bulk UPDATE, as a revocation runs it
        session.execute(update(WebSession).values(revoked_at=utcnow()))
        session.commit()
    assert epoch() != after
    latest = epoch()
    with engine.begin() as conn:  # Core, outside any ORM session
        conn.execute(text("UPDATE web_sessions SET revoked_at = NULL"))
    assert epoch() != latest


def test_reads_a_rolled_back_write_and_a_session_seen_again_leave_it(engine):
    from grader.core.models import User, WebSession, utcnow
    from grader.services.identity import sessions

    with Session(engine) as session:
        user = session.scalars(select(User)).first()
        secret = sessions.open_session(session=session, user=user)
        session.commit()
    before = epoch()
    with Session(engine) as session:
        session.scalars(select(User)).all()
        session.commit()
    with Session(engine) as session:
        session.execute(update(WebSession).values(revoked_at=utcnow()))
        session.rollback()
    assert epoch() == before
    with Session(engine) as session:  # seen again (last seen over a minute ago): its last_seen_at alone is written
        row = session.scalars(select(WebSession)).one()
        row.last_seen_at -= timedelta(minutes=5)
        session.commit()
    after_setup = epoch()
    with Session(engine) as session:
        assert sessions.session_user(session=session, secret=secret) is not None
        assert session.dirty
        session.commit()
    assert epoch() == after_setup
