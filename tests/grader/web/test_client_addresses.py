"""Whose address a request has (issue 44, finding 6c): X-Forwarded-For counts only from a configured proxy
(settings.forwarded_allow_ips, none by default), under the uvicorn that `grader run` starts (grader.embedded)."""

from __future__ import annotations

import socket
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
    server = embedded.start_api("127.0.0.1", port)
    try:
        yield f"http://127.0.0.1:{port}"
    finally:
        server.should_exit = True
        deadline = time.monotonic() + 10
        while time.monotonic() < deadline:  # closed before the fixture drops the database
            with socket.socket() as probe:
                if probe.connect_ex(("127.0.0.1", port)) != 0:
                    break
            time.sleep(0.05)


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
