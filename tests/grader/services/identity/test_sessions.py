"""Page sessions and API tokens end (issue 26): the cookie holds a server-side session, never the token; sign-out,
idleness and age end a session; tokens expire and are revoked by the CLI or a course's instructor, over HTTP."""

from __future__ import annotations

from datetime import datetime, timedelta

from click.testing import CliRunner
from sqlalchemy import select, update

from grader.core.db import new_session
from grader.core.security import hash_token
from grader.core.models import ApiToken, Course, User, WebSession, utcnow

COOKIE = "grader_session"


def _sign_in(api, who: str):
    api.client.cookies.clear()
    signed = api.client.post("/sign-in", data={"token": api.tokens[who], "next": "/submissions"},
                             follow_redirects=False)
    assert signed.status_code == 303, signed.text
    return signed


def _holding(api, cookie: str):
    """The client holding only this cookie (a browser that kept it, or one it was copied to)."""
    api.client.cookies.clear()
    api.client.cookies.set(COOKIE, cookie)
    return api.client


def _opens_pages(api, cookie: str) -> bool:
    page = _holding(api, cookie).get("/submissions", follow_redirects=False)
    assert page.status_code in (200, 303), page.text
    return page.status_code == 200


def _edit(model, where, **values) -> None:
    with new_session() as session:
        session.execute(update(model).where(where).values(**values))
        session.commit()


def _user_id(name: str) -> int:
    with new_session() as session:
        return session.scalar(select(User.id).where(User.name == name))


def test_the_cookie_holds_a_session_secret_and_sign_out_ends_it_for_every_copy(api):
    signed = _sign_in(api, "alice")
    cookie = api.client.cookies[COOKIE]
    assert cookie != api.tokens["alice"] and api.tokens["alice"] not in signed.headers["set-cookie"]
    with new_session() as session:
        row = session.scalar(select(WebSession).where(WebSession.secret_hash == hash_token(cookie)))
        assert row is not None and row.revoked_at is None and row.user.name == "alice"
        assert cookie not in {r.secret_hash for r in session.scalars(select(WebSession))}  # only its sha256
        assert timedelta(days=6) < row.expires_at - row.created_at <= timedelta(days=7)
    assert _opens_pages(api, cookie)
    out = _holding(api, cookie).post("/sign-out", follow_redirects=False)
    assert out.status_code == 303 and out.headers["location"] == "/sign-in"
    # The attack: a copy of the cookie kept after sign-out (a shared lab machine, a stolen cookie) still opened pages.
    assert not _opens_pages(api, cookie)
    with new_session() as session:
        assert session.scalar(select(WebSession.revoked_at).where(WebSession.secret_hash == hash_token(cookie)))


def test_a_session_ends_when_idle_and_at_its_lifetime_and_use_keeps_it_alive(api):
    _sign_in(api, "alice")
    idle = api.client.cookies[COOKIE]
    _sign_in(api, "bob")
    old = api.client.cookies[COOKIE]
    _edit(WebSession, WebSession.secret_hash == hash_token(idle), last_seen_at=utcnow() - timedelta(hours=11))
    assert _opens_pages(api, idle)  # 11 h idle: still open, and now seen again
    with new_session() as session:
        seen = session.scalar(select(WebSession.last_seen_at).where(WebSession.secret_hash == hash_token(idle)))
    assert utcnow() - seen < timedelta(minutes=1)
    _edit(WebSession, WebSession.secret_hash == hash_token(idle), last_seen_at=utcnow() - timedelta(hours=13))
    assert not _opens_pages(api, idle)
    _edit(WebSession, WebSession.secret_hash == hash_token(old), expires_at=utcnow() - timedelta(seconds=1))
    assert not _opens_pages(api, old)


def test_expired_and_revoked_tokens_answer_401_saying_which(api):
    _edit(ApiToken, ApiToken.user_id == _user_id("alice"), expires_at=utcnow() - timedelta(days=1))
    _edit(ApiToken, ApiToken.user_id == _user_id("bob"), revoked_at=utcnow())
    for who, word in (("alice", "expired"), ("bob", "revoked")):
        response = api.client.get("/v1/submissions", headers=api.as_(who))
        assert response.status_code == 401 and word in response.json()["detail"], response.text
        assert response.headers["www-authenticate"] == "Bearer"
        api.client.cookies.clear()
        form = api.client.post("/sign-in", data={"token": api.tokens[who]}, follow_redirects=False)
        assert form.status_code == 401 and word in form.text and COOKIE not in form.headers.get("set-cookie", "")
        page = api.client.get("/submissions", headers=api.as_(who), follow_redirects=False)
        assert page.status_code == 303  # the bearer header on a page: not signed in either
    unknown = api.client.get("/v1/submissions", headers={"Authorization": "Bearer l03_nothing"})
    assert unknown.status_code == 401 and unknown.json()["detail"] == "unknown token"


def test_a_session_never_outlives_its_token(api):
    _edit(ApiToken, ApiToken.user_id == _user_id("alice"), expires_at=utcnow() + timedelta(hours=1))
    _sign_in(api, "alice")
    with new_session() as session:
        row = session.scalar(select(WebSession).where(WebSession.secret_hash == hash_token(api.client.cookies[COOKIE])))
    assert row.expires_at - utcnow() <= timedelta(hours=1)


def test_new_tokens_expire_after_the_configured_lifetime_or_the_days_given(api):
    from grader.cli.service import admin

    with new_session() as session:
        made = session.scalar(select(ApiToken).where(ApiToken.token_hash == hash_token(api.tokens["alice"])))
    assert timedelta(days=179) < made.expires_at - utcnow() <= timedelta(days=180)
    result = CliRunner().invoke(admin, ["token", "l03", "carol", "--role", "student", "--expires-in", "7"])
    assert result.exit_code == 0, result.output
    with new_session() as session:
        row = session.scalar(select(ApiToken).where(ApiToken.token_hash == hash_token(result.output.strip())))
    assert timedelta(days=6) < row.expires_at - utcnow() <= timedelta(days=7)
    for days in ("0", "-3", "99999", "soon"):
        bad = CliRunner().invoke(admin, ["token", "l03", "carol", "--role", "student", "--expires-in", days])
        assert bad.exit_code == 2 and "--expires-in" in bad.output, bad.output


def test_admin_token_revoke_by_token_or_id_ends_the_token_and_its_page_sessions(api):
    from grader.cli.service import admin

    _sign_in(api, "alice")
    cookie = api.client.cookies[COOKIE]
    runner = CliRunner()
    revoked = runner.invoke(admin, ["token", "--revoke", api.tokens["alice"]])
    assert revoked.exit_code == 0 and "revoked" in revoked.output, revoked.output
    assert api.tokens["alice"] not in revoked.output
    response = api.client.get("/v1/submissions", headers=api.as_("alice"))
    assert response.status_code == 401 and "revoked" in response.json()["detail"]
    assert not _opens_pages(api, cookie)

    listed = runner.invoke(admin, ["token", "l03", "bob", "--list"])
    assert listed.exit_code == 0 and "revoked" not in listed.output, listed.output
    bob_id = listed.output.split()[0]
    assert runner.invoke(admin, ["token", "--revoke", bob_id]).exit_code == 0
    assert api.client.get("/v1/submissions", headers=api.as_("bob")).status_code == 401
    assert "revoked" in runner.invoke(admin, ["token", "l03", "bob", "--list"]).output
    assert api.client.get("/v1/submissions", headers=api.as_("prof")).status_code == 200  # nobody else's

    missing = runner.invoke(admin, ["token", "--revoke", "999999"])
    assert missing.exit_code == 1 and "not found" in missing.output
    mixed = runner.invoke(admin, ["token", "l03", "bob", "--revoke", bob_id])
    assert mixed.exit_code == 2 and "--revoke takes only" in mixed.output
    unknown = runner.invoke(admin, ["token", "nowhere", "bob", "--list"])
    assert unknown.exit_code == 1 and "not found" in unknown.output
    with new_session() as session:
        assert session.scalar(select(Course).where(Course.name == "nowhere")) is None  # listing creates nothing
    nothing = runner.invoke(admin, ["token"])
    assert nothing.exit_code == 2 and "COURSE NAME --role" in nothing.output


def test_an_instructor_revokes_a_students_tokens_and_sessions_in_their_own_course_only(api):
    _sign_in(api, "alice")
    alices_page = api.client.cookies[COOKIE]
    path = "/v1/courses/l03/students/{}/tokens/revoke"
    for who, name, code in (("alice", "bob", 403), ("tess", "alice", 403),  # a student, an auditor
                            ("eve", "alice", 404),  # another course's instructor
                            ("prof", "eve", 404), ("prof", "tess", 404), ("prof", "nobody", 404)):  # not a student here
        response = api.client.post(path.format(name), headers=api.as_(who))
        assert response.status_code == code, (who, name, response.text)
    other = api.client.post("/v1/courses/other/students/alice/tokens/revoke", headers=api.as_("prof"))
    assert other.status_code == 404
    assert api.client.get("/v1/submissions", headers=api.as_("alice")).status_code == 200  # nothing revoked yet

    response = api.client.post(path.format("alice"), headers=api.as_("prof"))
    assert response.status_code == 200, response.text
    assert response.json() == {"student": "alice", "tokens_revoked": 1, "sessions_revoked": 1}
    refused = api.client.get("/v1/submissions", headers=api.as_("alice"))
    assert refused.status_code == 401 and "revoked" in refused.json()["detail"]
    assert not _opens_pages(api, alices_page)
    assert api.client.get("/v1/submissions", headers=api.as_("bob")).status_code == 200
    again = api.client.post(path.format("alice"), headers=api.as_("prof"))
    assert again.json() == {"student": "alice", "tokens_revoked": 0, "sessions_revoked": 0}


def test_the_api_never_takes_the_page_cookie(api):
    _sign_in(api, "prof")
    assert api.client.get("/v1/submissions").status_code == 401
    assert api.client.post("/v1/courses/l03/students/alice/tokens/revoke").status_code == 401


def test_migration_0014_gives_every_existing_token_an_expiry_and_goes_down(tmp_path):
    from alembic import command
    from sqlalchemy import inspect, text

    from grader.core.db import make_engine, migrate
    from tests.grader.core.test_storage import alembic_config

    url = f"sqlite:///{tmp_path / 'm.db'}"
    migrate(url)
    config = alembic_config(url)
    command.downgrade(config, "0014-1")
    engine = make_engine(url)
    with engine.begin() as conn:
        conn.execute(text("INSERT INTO courses (name, created_at, timezone) VALUES ('c', CURRENT_TIMESTAMP, 'UTC')"))
        conn.execute(text("INSERT INTO users (course_id, name, role, created_at) VALUES (1, 'u', 'student', "
                          "CURRENT_TIMESTAMP)"))
        conn.execute(text("INSERT INTO api_tokens (user_id, token_hash, created_at) "
                          "VALUES (1, 'h', CURRENT_TIMESTAMP)"))
    command.upgrade(config, "head")
    with engine.connect() as conn:
        expires = conn.execute(text("SELECT expires_at FROM api_tokens")).scalar()
    assert timedelta(days=179) < datetime.fromisoformat(str(expires)) - utcnow() <= timedelta(days=180)
    command.downgrade(config, "0014-1")
    with engine.connect() as conn:
        assert "web_sessions" not in inspect(conn).get_table_names()
        assert "expires_at" not in {c["name"] for c in inspect(conn).get_columns("api_tokens")}
    engine.dispose()
