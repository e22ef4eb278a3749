"""A 304 with no database query (issue 35 item 3, grader.web.fresh): a conditional read of an unchanged complete
report is answered from the validator store, on Redis and on the embedded store, with no SQL statement; every write
(an override, a release, a token's revocation, a sign-out) and a due date passing make the next conditional read a
full one (200 or 401, never a stale 304); another reader's credential never gets one from someone else's entry; and
with the store down every read takes the database path, still right. Over the real app in-process, real grades
(checkpoint sheets graded on the lesson's cases as really measured)."""

from __future__ import annotations

import uuid
from contextlib import contextmanager
from datetime import UTC, timedelta

import pytest
from sqlalchemy import event, select

from tests.grader.web.test_etag import graded  # an assignment and its graded submission, as the ETag tests make them
from tests.grader.services.setup.test_assignments import lesson_cases_stored  # noqa: F401 - autouse: the lesson measured

READS = ("/submissions/{sid}", "/submissions/{sid}/results.json", "/v1/submissions/{sid}",
         "/v1/submissions/{sid}/grade")


@pytest.fixture(params=["embedded", "redis"])
def store(request, monkeypatch, tmp_path):
    """The validator store of this test alone: the embedded one (files under data_dir/broker) or a private Redis
    database; a key prefix of its own, so test processes side by side never bump each other's epoch."""
    from grader.core import freshness
    from grader.core.settings import settings
    from grader.web.etag import BODIES

    if request.param == "redis":
        from tests.services import REDIS_URL, redis_client

        redis_client()  # skips (fails on CI) where Redis is not reachable
        monkeypatch.setattr(settings, "broker_url", REDIS_URL)
    else:
        monkeypatch.setattr(settings, "broker_url", "filesystem://")
        monkeypatch.setattr(settings, "data_dir", tmp_path / "data")
    monkeypatch.setattr(freshness, "PREFIX", f"grader:fresh-test-{uuid.uuid4().hex[:12]}:")
    BODIES.clear()
    freshness._owed.clear()  # nothing owed or resting from another test's store
    freshness._failed_at[0] = float("-inf")
    yield request.param
    BODIES.clear()
    freshness._owed.clear()
    freshness._failed_at[0] = float("-inf")


@contextmanager
def statements():
    """Every SQL statement the app's engine runs within the block."""
    from grader.core import db

    ran: list[str] = []

    def note(_conn, _cursor, statement, *_args):
        ran.append(statement)

    engine = db.get_engine()
    event.listen(engine, "before_cursor_execute", note)
    try:
        yield ran
    finally:
        event.remove(engine, "before_cursor_execute", note)


def read(api, path: str, who="alice", tag: str | None = None, **headers):
    if tag:
        headers["If-None-Match"] = tag
    if who:
        headers |= api.as_(who)
    return api.client.get(path, headers=headers, follow_redirects=False)


def tags(api, sid, who="alice") -> dict[str, str]:
    out = {}
    for pattern in READS:
        response = read(api, pattern.format(sid=sid), who)
        assert response.status_code == 200, response.text
        out[pattern] = response.headers["etag"]
    return out


def from_memory(api, path: str, tag: str, who="alice", **headers) -> None:
    """The conditional read is a 304 with the route's headers and not one SQL statement."""
    with statements() as ran:
        response = read(api, path, who, tag=tag, **headers)
    assert response.status_code == 304, (path, response.status_code)
    assert ran == [], (path, ran)
    assert response.headers["etag"] == tag and response.headers["cache-control"] == "private, no-cache"
    assert response.content == b"" and response.headers["x-content-type-options"] == "nosniff"  # marked as any


def test_an_unchanged_report_answers_304_with_no_sql_on_every_read(api, store):
    _, sid = graded(api)
    for pattern, tag in tags(api, sid).items():
        from_memory(api, pattern.format(sid=sid), tag)
        # another tag: the full path answers in full, with the same validator
        full = read(api, pattern.format(sid=sid), tag='"not-this-one"')
        assert full.status_code == 200 and full.headers["etag"] == tag


def test_a_page_session_cookie_answers_from_memory_and_sign_out_ends_it(api, store):
    _, sid = graded(api)
    api.client.cookies.clear()
    signed = api.client.post("/sign-in", data={"token": api.tokens["alice"]}, follow_redirects=False)
    assert signed.status_code == 303, signed.text
    secret = api.client.cookies["grader_session"]
    page = read(api, f"/submissions/{sid}", who=None)
    assert page.status_code == 200, page.text
    from_memory(api, f"/submissions/{sid}", page.headers["etag"], who=None)
    assert api.client.post("/sign-out", follow_redirects=False).status_code == 303
    # The same cookie, kept: signed out, never a 304 from memory.
    again = api.client.get(f"/submissions/{sid}", headers={"If-None-Match": page.headers["etag"],
                                                          "Cookie": f"grader_session={secret}"},
                           follow_redirects=False)
    assert again.status_code == 303 and again.headers["location"].startswith("/sign-in"), again.status_code


def test_an_override_makes_the_next_conditional_read_a_full_one(api, store):
    _, sid = graded(api)
    before = tags(api, sid)
    made = api.client.post(f"/v1/submissions/{sid}/overrides", headers=api.as_("prof"),
                           json={"item_id": "C2", "score": 0, "comment": "The reason quotes the wrong condition."})
    assert made.status_code == 201, made.text
    for pattern, tag in before.items():
        response = read(api, pattern.format(sid=sid), tag=tag)
        assert response.status_code == 200 and response.headers["etag"] != tag, pattern
        from_memory(api, pattern.format(sid=sid), response.headers["etag"])
    assert read(api, f"/v1/submissions/{sid}/grade").json()["items"][1]["score"] == 0


def test_a_release_makes_the_next_conditional_read_a_full_one(api, store):
    aid, sid = graded(api, item_visibility={"C2": "on_release"})
    before = tags(api, sid)
    from_memory(api, f"/submissions/{sid}", before["/submissions/{sid}"])
    assert "1 of 8 points pending" in read(api, f"/submissions/{sid}").text
    assert api.client.post(f"/v1/assignments/{aid}/release", headers=api.as_("prof")).status_code == 200
    for pattern, tag in before.items():
        response = read(api, pattern.format(sid=sid), tag=tag)
        assert response.status_code == 200 and response.headers["etag"] != tag, pattern
    assert "points pending" not in read(api, f"/submissions/{sid}").text


def test_a_revoked_token_gets_401_not_a_304(api, store):
    from grader.core.db import new_session
    from grader.services.identity import accounts

    _, sid = graded(api)
    before = tags(api, sid)
    from_memory(api, f"/v1/submissions/{sid}", before["/v1/submissions/{sid}"])
    with new_session() as session:
        accounts.revoke_token(session=session, token_or_id=api.tokens["alice"])
        session.commit()
    assert read(api, f"/v1/submissions/{sid}", tag=before["/v1/submissions/{sid}"]).status_code == 401
    assert read(api, f"/v1/submissions/{sid}/grade", tag=before["/v1/submissions/{sid}/grade"]).status_code == 401
    page = read(api, f"/submissions/{sid}", tag=before["/submissions/{sid}"])
    assert page.status_code == 303 and page.headers["location"].startswith("/sign-in")


def test_a_due_date_passing_shows_the_item_at_once(api, store):
    from grader.core import clock

    start = clock.now().replace(microsecond=0, tzinfo=UTC)
    due = start + timedelta(seconds=30)  # sooner than the entries' last guard (freshness.ENTRY_TTL_S)
    with clock.frozen(start):
        _, sid = graded(api, open_at=(start - timedelta(days=1)).isoformat(), due_at=due.isoformat(),
                        item_visibility={"C2": "after_due"})
        page = read(api, f"/submissions/{sid}")
        assert "1 of 8 points pending" in page.text
        from_memory(api, f"/submissions/{sid}", page.headers["etag"])
    with clock.frozen(due - timedelta(seconds=1)):  # still withheld: still answered from memory
        from_memory(api, f"/submissions/{sid}", page.headers["etag"])
    with clock.frozen(due + timedelta(seconds=1)):
        with statements() as ran:
            after = read(api, f"/submissions/{sid}", tag=page.headers["etag"])
        assert after.status_code == 200 and after.headers["etag"] != page.headers["etag"] and ran
        assert "points pending" not in after.text


def test_another_readers_credential_never_gets_a_304_from_someone_elses_entry(api, store):
    _, sid = graded(api)
    mine = tags(api, sid)
    for pattern, tag in mine.items():
        path = pattern.format(sid=sid)
        from_memory(api, path, tag)
        staff = read(api, path, "prof", tag=tag)  # may read it, but their answer is their own
        assert staff.status_code == 200 and staff.headers["etag"] != tag, path
        outsider = read(api, path, "bob", tag=tag)  # may not read it at all
        assert outsider.status_code == 404 and "etag" not in outsider.headers, path
        nobody = read(api, path, None, tag=tag)
        assert nobody.status_code in (303, 401), path


def test_with_the_store_down_every_read_takes_the_database_path(api, store, monkeypatch):
    from grader.core.settings import settings
    from tests.services import free_port

    _, sid = graded(api)
    before = tags(api, sid)
    monkeypatch.setattr(settings, "broker_url", f"redis://127.0.0.1:{free_port()}/0")  # nothing listens there
    for pattern, tag in before.items():
        with statements() as ran:
            response = read(api, pattern.format(sid=sid), tag=tag)
        assert response.status_code == 304 and ran, pattern  # the route's own 304, from the database
    made = api.client.post(f"/v1/submissions/{sid}/overrides", headers=api.as_("prof"),
                           json={"item_id": "C2", "score": 0, "comment": "The reason quotes the wrong condition."})
    assert made.status_code == 201, made.text  # a write whose epoch cannot be bumped still commits
    for pattern, tag in before.items():
        response = read(api, pattern.format(sid=sid), tag=tag)
        assert response.status_code == 200 and response.headers["etag"] != tag, pattern


def test_a_token_that_expires_is_refused_at_once_not_confirmed_from_memory(api, store):
    """An entry ends with the reader's credential: a token expiring sooner than the entries' last guard
    (freshness.ENTRY_TTL_S) gets 401 at its expiry, not a 304 from an entry written while it was good."""
    from grader.core import clock
    from grader.core.db import new_session
    from grader.core.models import User
    from grader.services.identity import accounts

    start = clock.now().replace(microsecond=0)
    with clock.frozen(start.replace(tzinfo=UTC)):
        _, sid = graded(api)
        with new_session() as session:
            alice = session.scalars(select(User).where(User.name == "alice")).one()
            short = accounts.create_token(session=session, user=alice, expires_in_days=1)
            session.commit()
    expiry = start + timedelta(days=1)
    bearer = {"Authorization": f"Bearer {short}"}
    path = f"/v1/submissions/{sid}"
    with clock.frozen((expiry - timedelta(seconds=30)).replace(tzinfo=UTC)):
        first = read(api, path, None, **bearer)
        assert first.status_code == 200, first.text
        from_memory(api, path, first.headers["etag"], None, **bearer)
    with clock.frozen((expiry - timedelta(seconds=1)).replace(tzinfo=UTC)):  # still good: still from memory
        from_memory(api, path, first.headers["etag"], None, **bearer)
    with clock.frozen((expiry + timedelta(seconds=1)).replace(tzinfo=UTC)):
        expired = read(api, path, None, tag=first.headers["etag"], **bearer)
        assert expired.status_code == 401 and "expired" in expired.json()["detail"], expired.status_code


def test_two_students_page_sessions_never_share_an_entry(api, store):
    """The Cookie header is part of the entry's key: bob's page session, sent with alice's ETag for her report, is
    answered by the route (not found: it is not his), never 304 from alice's entry."""
    _, sid = graded(api)
    cookies = {}
    for who in ("alice", "bob"):
        api.client.cookies.clear()
        signed = api.client.post("/sign-in", data={"token": api.tokens[who]}, follow_redirects=False)
        assert signed.status_code == 303, signed.text
        cookies[who] = f"grader_session={api.client.cookies['grader_session']}"
    api.client.cookies.clear()
    for pattern in ("/submissions/{sid}", "/submissions/{sid}/results.json"):
        path = pattern.format(sid=sid)
        mine = read(api, path, None, Cookie=cookies["alice"])
        assert mine.status_code == 200, mine.text
        from_memory(api, path, mine.headers["etag"], None, Cookie=cookies["alice"])
        theirs = read(api, path, None, tag=mine.headers["etag"], Cookie=cookies["bob"])
        assert theirs.status_code == 404 and "etag" not in theirs.headers, (path, theirs.status_code)


def test_a_write_landing_while_a_report_is_read_retires_the_entry_that_read_keeps(api, store):
    """The entry is kept under the epoch read before the request's first database read: a write committed after the
    report's rows were read (here alice's token revoked, by another session, just as the route reads the report's
    review requests) leaves the entry under the old epoch, so the next conditional read is a full one (401)."""
    import threading

    from grader.core import db
    from grader.core.db import new_session
    from grader.services.identity import accounts

    _, sid = graded(api)
    path = f"/v1/submissions/{sid}"
    armed = [True]

    def revoke():
        with new_session() as session:
            accounts.revoke_token(session=session, token_or_id=api.tokens["alice"])
            session.commit()

    def write_meanwhile(_conn, _cursor, statement, *_args):
        if armed[0] and "FROM review_requests" in statement:  # grader.web.etag.report_state: its last read
            armed[0] = False
            writer = threading.Thread(target=revoke)  # another request's commit, not this one's session
            writer.start()
            writer.join()

    engine = db.get_engine()
    event.listen(engine, "after_cursor_execute", write_meanwhile)
    try:
        answered = read(api, path)
    finally:
        event.remove(engine, "after_cursor_execute", write_meanwhile)
    assert not armed[0] and answered.status_code == 200, answered.text  # built from the rows read before the write
    again = read(api, path, tag=answered.headers["etag"])
    assert again.status_code == 401, again.status_code


def test_a_bump_skipped_while_the_store_rests_is_paid_before_memory_answers_again(api, store, monkeypatch):
    """A read that finds the store failing leaves it alone a moment (freshness.RETRY_S); a write committed meanwhile
    cannot change the epoch, so the process owes the bump, and once the store answers again it pays it before
    trusting any entry: the revoked token gets 401, never a 304 from an entry written before the revocation."""
    import time

    from grader.core import freshness
    from grader.core.db import new_session
    from grader.core.settings import settings
    from grader.services.identity import accounts
    from tests.services import free_port

    _, sid = graded(api)
    path = f"/v1/submissions/{sid}"
    first = read(api, path)
    assert first.status_code == 200, first.text
    from_memory(api, path, first.headers["etag"])
    working = settings.broker_url
    monkeypatch.setattr(settings, "broker_url", f"redis://127.0.0.1:{free_port()}/0")  # nothing listens there
    during = read(api, path, tag=first.headers["etag"])  # the store fails this read: the database answers
    assert during.status_code == 304, during.status_code
    with new_session() as session:  # within the rest that failure began: the bump is not even tried
        accounts.revoke_token(session=session, token_or_id=api.tokens["alice"])
        session.commit()
    monkeypatch.setattr(settings, "broker_url", working)  # the store is back
    time.sleep(freshness.RETRY_S + 0.1)  # past the rest
    again = read(api, path, tag=first.headers["etag"])
    assert again.status_code == 401, again.status_code
