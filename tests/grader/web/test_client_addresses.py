"""One client address under the uvicorn that `grader run` starts (grader.embedded), issue 44 finding 6: whose address
a request has (X-Forwarded-For counts only from a configured proxy, settings.forwarded_allow_ips, none by default),
and the embedded service's own progress poll, refused while other requests of its address stall (429), waits."""

from __future__ import annotations

import socket
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager

import httpx

from tests.services import free_port


@contextmanager
def embedded_api() -> Iterator[str]:
    """The app under the embedded service's own uvicorn (grader.embedded.start_api) on loopback, on the test's
    database (the `api` fixture's settings); its URL."""
    from grader import embedded

    port = free_port()
    server, thread = embedded.start_api("127.0.0.1", port)
    try:
        yield f"http://127.0.0.1:{port}"
    finally:
        server.should_exit = True
        thread.join(timeout=10)  # closed before the fixture drops the database


def wrong_sign_ins(url: str, forwarded_for: list[str]) -> list[int]:
    """The status of one wrong sign-in per X-Forwarded-For given, in order, each from 127.0.0.1."""
    with httpx.Client(base_url=url, timeout=30) as client:
        return [client.post("/sign-in", data={"token": "not-a-token"}, headers={"X-Forwarded-For": address},
                            follow_redirects=False).status_code
                for address in forwarded_for]


def test_a_loopback_client_naming_other_addresses_is_still_refused_by_the_sign_in_limit(api):
    from grader.core.settings import settings

    assert settings.rate_limit_sign_in_failures == "20/10 minutes"  # and FORWARDED_ALLOW_IPS as by default: unset
    with embedded_api() as url:
        codes = wrong_sign_ins(url, [f"203.0.113.{i}" for i in range(1, 26)])
    assert codes == [401] * 20 + [429] * 5, codes


def test_behind_a_configured_proxy_the_forwarded_address_is_the_clients(api, monkeypatch):
    from grader.core.settings import settings

    monkeypatch.setattr(settings, "forwarded_allow_ips", ["127.0.0.1"])  # the proxy runs on this host
    with embedded_api() as url:
        others = wrong_sign_ins(url, [f"203.0.113.{i}" for i in range(1, 26)])
        one = wrong_sign_ins(url, ["198.51.100.7"] * 21)
        # A forwarded chain: the rightmost address the proxy did not add is the client's (uvicorn's rule).
        chained = wrong_sign_ins(url, ["10.9.9.9, 198.51.100.7, 127.0.0.1"])
        another = wrong_sign_ins(url, ["198.51.100.8"])
    assert others == [401] * 25, others  # each address has its own count
    assert one == [401] * 20 + [429], one
    assert chained == [429] and another == [401]


def test_the_progress_poll_waits_out_a_429_while_its_address_is_full_of_stalled_bodies(api, monkeypatch):
    """As in the finding: anonymous requests from 127.0.0.1 that never send their bodies fill the address's requests
    in flight (settings.client_max_in_flight, 2 here, 20 by default), so the embedded service's poll is refused."""
    from grader.client import Client
    from grader.core.db import new_session
    from grader.core.models import Submission
    from grader.core.settings import settings
    from grader.core.states import SubmissionState
    from tests.factories import reference_sheet

    created = api.client.post("/v1/submissions", json={"sheet": reference_sheet()}, headers=api.as_("alice"))
    assert created.status_code == 202, created.text
    with new_session() as session:  # a submission that ends at the first answer the poll gets
        session.get(Submission, created.json()["id"]).status = SubmissionState.FAILED
        session.commit()
    monkeypatch.setattr(settings, "client_max_in_flight", 2)
    with embedded_api() as url:
        port = int(url.rsplit(":", 1)[1])
        stalled = [socket.create_connection(("127.0.0.1", port)) for _ in range(2)]
        for connection in stalled:  # headers, and a body that never comes
            connection.sendall(b"POST /v1/submissions HTTP/1.1\r\nHost: 127.0.0.1\r\n"
                               b"Content-Type: application/json\r\nContent-Length: 100\r\n\r\n")
        deadline = time.monotonic() + 10
        while httpx.get(f"{url}/v1/health").status_code != 429:
            assert time.monotonic() < deadline, "the stalled bodies never filled the address"
            time.sleep(0.05)
        threading.Timer(2.5, lambda: [connection.close() for connection in stalled]).start()
        client = Client(url, api.tokens["alice"])
        answers = []
        client.http.event_hooks["response"] = [lambda response: answers.append(response.status_code)]
        started = time.monotonic()
        state = client.wait(created.json()["id"], poll_s=0.1, timeout_s=30)
        waited = time.monotonic() - started
    assert state["status"] == SubmissionState.FAILED
    assert answers[0] == 429 and answers[-1] == 200 and set(answers) == {429, 200}, answers
    # Each refusal said Retry-After: 1, and the poll waited that long rather than polling at once (every 0.1 s).
    assert answers.count(429) <= 4 and waited >= 2.0, (answers, waited)
