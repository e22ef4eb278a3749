"""The database engine (one per process), sessions, and schema migration through Alembic."""

from __future__ import annotations

import re
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from sqlalchemy import Engine, create_engine, event
from sqlalchemy.orm import Session
from sqlalchemy.pool import Pool

from grader.core import freshness
from grader.core.settings import settings

MIGRATIONS = Path(__file__).resolve().parent.parent / "migrations"
_engine: Engine | None = None


def make_engine(url: str) -> Engine:
    """An engine whose pool holds a connection for every request the API admits (settings.api_threads) plus
    db_pool_overflow; connections open only when used, so a worker or the CLI holds few."""
    pool = {"pool_size": settings.api_threads, "max_overflow": settings.db_pool_overflow}
    if url.startswith("sqlite"):
        Path(url.split("///", 1)[1]).parent.mkdir(parents=True, exist_ok=True)
        # A file database pools like a server's (QueuePool): SQLite connections are cheap, WAL serves readers at once.
        engine = create_engine(url, connect_args={"timeout": 30, "check_same_thread": False}, **pool)

        @event.listens_for(engine, "connect")
        def _sqlite_pragmas(dbapi_connection, _record):
            # WAL lets the API read while a worker writes; foreign keys are off by default in SQLite.
            cursor = dbapi_connection.cursor()
            cursor.execute("PRAGMA journal_mode=WAL")
            cursor.execute("PRAGMA foreign_keys=ON")
            cursor.close()

        return engine
    return create_engine(url, pool_pre_ping=True, **pool)


# The write epoch (grader.core.freshness) changes after every commit that wrote anything, on every engine of the
# process (the service's, a test's, a migration's): a statement that writes marks its connection, the commit turns
# the mark into a bump owed, and the bump is made once the commit is done (the connection back in the pool, or its
# next transaction begun), never before: a reader must not see the new epoch with the old rows.
_WROTE, _OWED = "grader_wrote", "grader_bump_owed"
# Every statement but those known to read counts as a write (a CTE, DDL, anything new): a needless bump costs a
# full read, a missed one a stale 304.
_READS = re.compile(r"\s*(SELECT|PRAGMA|SHOW|EXPLAIN|BEGIN|SAVEPOINT|RELEASE|ROLLBACK|COMMIT|SET)\b", re.I)
# Seeing a page sign-in session again (grader.services.identity.sessions.session_user) is no change to anything a
# reader is answered: it alone does not retire the validators. Revoking one sets revoked_at, and does.
_TOUCH = re.compile(r"\s*UPDATE web_sessions SET last_seen_at=\S+ WHERE web_sessions\.id = \S+\s*$")


@event.listens_for(Engine, "before_cursor_execute")
def _mark_writes(conn, _cursor, statement, _parameters, _context, _executemany):
    if conn.info.pop(_OWED, False):  # the transaction that wrote is committed: a new one is starting
        freshness.bump()
    if not _READS.match(statement) and not _TOUCH.match(statement):
        conn.info[_WROTE] = True


@event.listens_for(Engine, "commit")
def _owe_bump(conn):
    if conn.info.pop(_WROTE, False):
        conn.info[_OWED] = True


@event.listens_for(Engine, "rollback")
def _forget_writes(conn):
    conn.info.pop(_WROTE, None)


@event.listens_for(Pool, "checkin")
def _pay_bump(_dbapi_connection, record):
    if record is not None and record.info.pop(_OWED, False):
        freshness.bump()


def get_engine() -> Engine:
    """This process's engine, created on first use from settings.database_url."""
    global _engine
    if _engine is None:
        _engine = make_engine(settings.database_url)
    return _engine


def new_session() -> Session:
    return Session(get_engine(), expire_on_commit=False)


@contextmanager
def snapshot(session: Session) -> Iterator[Session]:
    """The reads inside see the database as of one moment: whatever commits meanwhile is seen by none of them or all.

    Without this, consecutive SELECTs are not one snapshot on either database: PostgreSQL's default isolation (READ
    COMMITTED) takes a fresh snapshot per statement, and SQLite under the pysqlite driver's legacy transaction
    handling sends BEGIN only before a write, so each SELECT reads the database as it is then (issue 49: a page read a
    run's state as queued, a worker claimed it, and the queue order read next no longer had it).

    The session's transaction so far ends first (committed: what it wrote is kept; a transaction's snapshot is taken
    at its start, which is past) and what it loaded is expired, so the objects the reads use come from the snapshot.
    The snapshot is one transaction: REPEATABLE READ on PostgreSQL; on SQLite an explicit BEGIN, whose first read fixes
    what it sees (WAL: writers go on meanwhile). It ends on the way out (committed, nothing written; rolled back on an
    error), so a write the caller makes next is not refused for reading an old snapshot."""
    if session.in_transaction():
        session.commit()
    session.expire_all()
    if session.get_bind().dialect.name == "postgresql":
        session.connection(execution_options={"isolation_level": "REPEATABLE READ"})
    else:
        connection = session.connection()
        if not connection.connection.dbapi_connection.in_transaction:
            connection.exec_driver_sql("BEGIN")
    try:
        yield session
    except BaseException:
        session.rollback()
        raise
    session.commit()


def migrate(url: str | None = None) -> None:
    """Bring the schema to the newest Alembic revision."""
    # lazy: Alembic (~0.3 s) only for migrations; the API, every worker and the CLI import this module without it
    from alembic import command
    from alembic.config import Config

    config = Config()
    config.set_main_option("script_location", str(MIGRATIONS))
    config.set_main_option("sqlalchemy.url", (url or settings.database_url).replace("%", "%%"))
    if (url or settings.database_url).startswith("sqlite"):
        get_engine() if url is None else make_engine(url).dispose()  # creates the folder
    command.upgrade(config, "head")
