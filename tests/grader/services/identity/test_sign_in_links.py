"""Students sign in with a link (issue 22, item 1): issued by the roster import and re-issued one at a time, stored
only as a hash, shown on a GET that uses nothing up, used once by a POST that opens the sign-in form's session;
refused with a clear page when used, replaced or expired."""

from __future__ import annotations

import re
from datetime import timedelta

from sqlalchemy import func, select, update

from grader.core.db import new_session
from grader.core.security import hash_token
from grader.core.models import SignInLink, User, WebSession, utcnow
from tests.grader.cli.test_assignment_cli import run
from tests.grader.services.setup.test_assignments import ROSTER

COOKIE = "grader_session"
LINK = re.compile(r"^http://testserver/sign-in/link/([A-Za-z0-9_-]{43})$")


def _import(api, links=True, who="prof"):
    return api.client.post("/v1/courses/l03/roster", json={"csv": ROSTER, "links": links}, headers=api.as_(who))


def _reissue(api, student, who="prof"):
    return api.client.post(f"/v1/courses/l03/students/{student}/sign-in-link", headers=api.as_(who))


def _path(link: str) -> str:
    match = LINK.match(link)
    assert match, link
    return "/sign-in/link/" + match.group(1)


def _sessions() -> int:
    with new_session() as session:
        return session.scalar(select(func.count()).select_from(WebSession))


def _use(api, path, **headers):
    api.client.cookies.clear()
    return api.client.post(path, follow_redirects=False, headers=headers)


def test_a_roster_link_shows_a_confirmation_then_signs_in_once_into_a_session(api):
    imported = _import(api)
    assert imported.status_code == 200, imported.text
    ada = {e["student"]: e for e in imported.json()}["s1001"]
    path = _path(ada["sign_in_link"])
    secret = path.rsplit("/", 1)[1]
    with new_session() as session:
        row = session.scalar(select(SignInLink).join(User).where(User.name == "s1001"))
        assert row.secret_hash == hash_token(secret)  # only the hash: the secret is in no column
        assert row.expires_at - row.created_at == timedelta(days=14) and row.used_at is None
    # A mail client's link scanner follows the GET: it must not use the link up.
    for _ in range(2):
        shown = api.client.get(path)
        assert shown.status_code == 200 and "Sign in as s1001" in shown.text and "Ada Lovelace" in shown.text
        assert COOKIE not in shown.cookies and _sessions() == 0
    used = _use(api, path)
    assert used.status_code == 303 and used.headers["location"] == "/courses/l03", used.text
    cookie = used.cookies[COOKIE]
    assert cookie != secret
    with new_session() as session:
        opened = session.scalar(select(WebSession).where(WebSession.secret_hash == hash_token(cookie)))
        assert opened.user.name == "s1001" and opened.revoked_at is None
    api.client.cookies.set(COOKIE, cookie)
    page = api.client.get("/submissions", follow_redirects=False)
    assert page.status_code == 200 and "signed in as <strong>s1001</strong>" in page.text
    # The attack: the same link used a second time (forwarded mail, a shared inbox) signed someone in again.
    again = _use(api, path)
    assert again.status_code == 410 and "already used" in again.text and COOKIE not in again.cookies
    assert _sessions() == 1
    assert "already used" in api.client.get(path).text


def test_a_reissued_link_revokes_the_earlier_one(api):
    first = _path(_reissue(api, "alice").json()["sign_in_link"])
    issued = _reissue(api, "alice")
    assert issued.status_code == 200 and issued.json()["student"] == "alice"
    second = _path(issued.json()["sign_in_link"])
    refused = _use(api, first)
    assert refused.status_code == 410 and "revoked at" in refused.text and "a newer link was issued" in refused.text
    assert _sessions() == 0
    assert _use(api, second).status_code == 303 and _sessions() == 1


def test_an_expired_link_is_refused_with_a_clear_page_and_opens_nothing(api):
    path = _path(_reissue(api, "alice").json()["sign_in_link"])
    with new_session() as session:
        session.execute(update(SignInLink).values(expires_at=utcnow() - timedelta(seconds=1)))
        session.commit()
    shown = api.client.get(path)
    assert shown.status_code == 410 and "expired at" in shown.text and 'action="/sign-in/link' not in shown.text
    used = _use(api, path)
    assert used.status_code == 410 and "expired at" in used.text and COOKIE not in used.cookies and _sessions() == 0


def test_an_unknown_link_and_a_cross_site_post_open_nothing(api):
    unknown = _use(api, "/sign-in/link/" + "A" * 43)
    assert unknown.status_code == 404 and "unknown" in unknown.text
    path = _path(_reissue(api, "alice").json()["sign_in_link"])
    # Another site's page making a browser post the victim's (or the attacker's own) link: refused, link unused.
    forged = _use(api, path, **{"Sec-Fetch-Site": "cross-site"})
    assert forged.status_code == 403 and _sessions() == 0
    assert _use(api, path).status_code == 303


def test_only_a_courses_instructor_issues_links_and_only_to_its_students(api):
    assert _reissue(api, "alice", who="alice").status_code == 403
    assert _reissue(api, "alice", who="tess").status_code == 403
    assert api.client.post("/v1/courses/l03/students/alice/sign-in-link", headers=api.as_("eve")).status_code == 404
    for student, rule in (("prof", "on the course staff"), ("nobody", "no student 'nobody'")):
        refused = _reissue(api, student)
        assert refused.status_code == 422, refused.text
        (error,) = refused.json()["errors"]
        assert error["field"] == "student" and rule in error["rule"]
    with new_session() as session:
        assert session.scalar(select(func.count()).select_from(SignInLink)) == 0
    plain = _import(api, links=False)
    assert plain.status_code == 200 and [e["sign_in_link"] for e in plain.json()] == [None, None]


def test_the_cli_imports_with_links_and_reissues_one(api, monkeypatch, tmp_path):
    roster_csv = tmp_path / "roster.csv"
    roster_csv.write_text(ROSTER)
    out = tmp_path / "tokens.csv"
    imported = run(api, monkeypatch, "roster", "import", "l03", str(roster_csv), "--links", "--tokens-out", str(out))
    assert imported.exit_code == 0, imported.output
    lines = out.read_text().splitlines()
    assert lines[0] == "student_id,token,sign_in_link" and [line.split(",")[0] for line in lines[1:]] == ["s1001",
                                                                                                        "s1002"]
    link = lines[1].split(",")[2]
    assert link not in imported.output and "each link works once, until 20" in imported.output
    reissued = run(api, monkeypatch, "roster", "link", "l03", "s1001")
    assert reissued.exit_code == 0, reissued.output
    new_link = reissued.output.split()[1]
    assert _use(api, _path(link)).status_code == 410 and _use(api, _path(new_link)).status_code == 303
    stranger = run(api, monkeypatch, "roster", "link", "l03", "nobody")
    assert stranger.exit_code != 0 and "student: no student 'nobody'" in stranger.output


def test_revoking_a_students_access_also_ends_their_unused_link(api):
    path = _path(_reissue(api, "alice").json()["sign_in_link"])
    revoked = api.client.post("/v1/courses/l03/students/alice/tokens/revoke", headers=api.as_("prof"))
    assert revoked.status_code == 200, revoked.text
    # The attack: a student whose access was revoked still held a mailed link, which opened a new session.
    refused = _use(api, path)
    assert refused.status_code == 410 and "revoked at" in refused.text and COOKIE not in refused.cookies
    assert _sessions() == 0
    assert _use(api, _path(_reissue(api, "alice").json()["sign_in_link"])).status_code == 303  # let back in on purpose
