"""Sign-in links' secrets stay out of the access log under plain `uvicorn grader.main:app` (the image's command), and
re-issuing a student's link ends the page sessions the earlier link opened (issue 31, item 5)."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import time

import httpx

from grader.services.identity.sign_in_links import PATH
from tests.factories import ROOT

COOKIE = "grader_session"


def _link(api, student: str = "alice") -> str:
    issued = api.client.post(f"/v1/courses/l03/students/{student}/sign-in-link", headers=api.as_("prof"))
    assert issued.status_code == 200, issued.text
    return issued.json()["sign_in_link"].rsplit("/", 1)[1]


def _serve(tmp_path, listener: socket.socket) -> subprocess.Popen:
    """`uvicorn grader.main:app` on an inherited socket bound to port 0, with its default log configuration."""
    env = {**os.environ, "DATABASE_URL": f"sqlite:///{tmp_path / 'grader.db'}", "DATA_DIR": str(tmp_path / "data"),
           "PYTHONUNBUFFERED": "1"}
    return subprocess.Popen([sys.executable, "-m", "uvicorn", "grader.main:app", "--fd", str(listener.fileno())],
                            cwd=ROOT, env=env, pass_fds=(listener.fileno(),), stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True)


def _wait_until_up(url: str, server: subprocess.Popen, within_s: float = 120) -> None:
    deadline = time.monotonic() + within_s
    while time.monotonic() < deadline:
        assert server.poll() is None, server.stdout.read()
        try:
            if httpx.get(f"{url}/v1/health", timeout=2).status_code == 200:
                return
        except httpx.TransportError:
            pass
        time.sleep(0.2)
    raise AssertionError("the server did not answer /v1/health")


def test_the_access_log_never_holds_a_links_secret(api, tmp_path):
    secret, other = _link(api, "alice"), _link(api, "bob")
    listener = socket.socket()
    listener.bind(("127.0.0.1", 0))
    listener.listen()
    url = f"http://127.0.0.1:{listener.getsockname()[1]}"
    server = _serve(tmp_path, listener)
    try:
        _wait_until_up(url, server)
        shown = httpx.get(f"{url}{PATH}{secret}?from=mail")
        assert shown.status_code == 200 and "Sign in as alice" in shown.text, shown.text
        used = httpx.post(f"{url}{PATH}{other}", follow_redirects=False)
        assert used.status_code == 303, used.text
        assert httpx.get(f"{url}{PATH}{'A' * 43}").status_code == 404
    finally:
        server.send_signal(signal.SIGINT)
        log, _ = server.communicate(timeout=60)
        listener.close()
    assert f'"GET {PATH}[secret]?from=mail HTTP/1.1" 200' in log, log
    assert f'"POST {PATH}[secret] HTTP/1.1" 303' in log, log
    for leaked in (secret, other, "A" * 43):
        assert leaked not in log, log


def test_redacting_keeps_the_rest_of_the_access_record():
    import logging

    from grader.web import logs

    record = logging.LogRecord("uvicorn.access", logging.INFO, __file__, 1, '%s - "%s %s HTTP/%s" %d',
                               ("10.0.0.1:5000", "GET", f"{PATH}s3cr3t-_x/extra?next=/a", "1.1", 200), None)
    assert logs.RedactSecrets().filter(record)
    assert record.getMessage() == f'10.0.0.1:5000 - "GET {PATH}[secret]/extra?next=/a HTTP/1.1" 200'


def test_reissuing_a_link_ends_the_sessions_the_earlier_link_opened(api):
    first = _link(api)
    used = api.client.post(f"{PATH}{first}", follow_redirects=False)
    assert used.status_code == 303, used.text
    by_link = used.cookies[COOKIE]
    api.client.cookies.clear()
    by_token = api.client.post("/sign-in", data={"token": api.tokens["alice"]}, follow_redirects=False)
    assert by_token.status_code == 303
    by_token = by_token.cookies[COOKIE]
    api.client.cookies.clear()

    def signed_in(cookie: str) -> bool:
        api.client.cookies.set(COOKIE, cookie)
        page = api.client.get("/submissions", follow_redirects=False)
        api.client.cookies.clear()
        return page.status_code == 200 and "signed in as <strong>alice</strong>" in page.text

    assert signed_in(by_link) and signed_in(by_token)
    second = _link(api)  # the instructor re-issues: the earlier link may be in other hands
    assert not signed_in(by_link), "the earlier link's session still works"
    assert signed_in(by_token), "a session the link did not open is not ended"
    assert api.client.post(f"{PATH}{second}", follow_redirects=False).status_code == 303
