"""Slow clients against the real API under uvicorn on loopback (issue 26): 40 connections that send headers and
then hold their body once took every admission slot, and /v1/health timed out for as long as they stayed open. A
body must now arrive within its deadline (408) before the request is admitted, and one client address has at most
a few requests in flight (429 beyond).

Loopback is 127.0.0.0/8, so each connection can come from its own address, as from many machines."""

from __future__ import annotations

import json
import os
import socket
import time

import httpx
import pytest

from tests import services

DEADLINE_S = 2.0
PER_CLIENT = 5
STALLED = 40  # the issue's count, and settings.api_threads' default: one per admission slot


@pytest.fixture(scope="module")
def api_url(tmp_path_factory):
    from grader.core.db import migrate

    data_dir = tmp_path_factory.mktemp("slow-clients")
    database_url = f"sqlite:///{data_dir / 'grader.db'}"
    migrate(database_url)
    env = dict(os.environ, DATA_DIR=str(data_dir), DATABASE_URL=database_url, PYTHONPATH=str(services.ROOT),
               BODY_DEADLINE_S=str(DEADLINE_S), CLIENT_MAX_IN_FLIGHT=str(PER_CLIENT), API_THREADS=str(STALLED))
    port = services.free_port()
    api = services.start_api(env, port, data_dir / "api.log")
    try:
        yield port
    finally:
        services.stop(api)


def stalled(port: int, path: str, *, source: str = "127.0.0.1") -> socket.socket:
    """A request whose headers promise 100 bytes of body, of which one is sent and the rest never."""
    conn = socket.create_connection(("127.0.0.1", port), timeout=DEADLINE_S + 10, source_address=(source, 0))
    conn.sendall(f"POST {path} HTTP/1.1\r\nHost: grader\r\nContent-Type: application/json\r\n"
                 "Content-Length: 100\r\n\r\n{".encode())
    return conn


def answer(conn: socket.socket) -> tuple[int, dict[str, str], bytes]:
    """The status, headers and body of the one answer on conn (the server closes it after)."""
    data = b""
    while chunk := conn.recv(65536):
        data += chunk
    conn.close()
    head, _, body = data.partition(b"\r\n\r\n")
    status_line, *lines = head.decode().split("\r\n")
    headers = {k.lower(): v.strip() for k, _, v in (line.partition(":") for line in lines)}
    return int(status_line.split()[1]), headers, body


def health(port: int, source: str = "127.0.0.1") -> httpx.Response:
    with httpx.Client(transport=httpx.HTTPTransport(local_address=source), timeout=2.0) as client:
        return client.get(f"http://127.0.0.1:{port}/v1/health")


@pytest.mark.timeout(60)
def test_forty_stalled_bodies_leave_health_answering_and_each_gets_408_after_the_deadline(api_url):
    port = api_url
    opened = time.monotonic()
    # Forty clients, each from its own address (one page form among them), so the per-client cap plays no part.
    conns = [stalled(port, "/sign-in" if i == 0 else "/v1/submissions", source=f"127.0.0.{10 + i}")
             for i in range(STALLED)]
    time.sleep(0.3)  # every request has reached the app and waits for its body
    started = time.monotonic()
    response = health(port)  # httpx raises ReadTimeout after 2 s: the old answer while the slots were held
    assert response.status_code == 200 and time.monotonic() - started < 2.0
    answers = [answer(c) for c in conns]
    waited = time.monotonic() - opened
    assert DEADLINE_S <= waited < DEADLINE_S + 10
    page_status, page_headers, page = answers[0]
    assert page_status == 408 and page_headers["content-type"].startswith("text/html")
    assert b"must arrive whole within 2 s" in page
    for status, headers, body in answers[1:]:
        assert status == 408 and headers["connection"] == "close"
        assert json.loads(body)["errors"] == [{"field": "body", "rule": "must arrive whole within 2 s of the request"}]


@pytest.mark.timeout(60)
def test_one_address_gets_at_most_its_share_of_requests_in_flight(api_url):
    port = api_url
    conns = [stalled(port, "/v1/submissions", source="127.0.0.2") for _ in range(PER_CLIENT)]
    time.sleep(0.3)
    refused = health(port, source="127.0.0.2")
    assert refused.status_code == 429 and refused.headers["retry-after"] == "1"
    assert refused.json()["errors"] == [{"field": "client", "rule": f"at most {PER_CLIENT} requests in flight from "
                                                                    "one address"}]
    assert health(port, source="127.0.0.3").status_code == 200  # another client is served meanwhile
    assert {answer(c)[0] for c in conns} == {408}
    assert health(port, source="127.0.0.2").status_code == 200  # its share is back once its requests ended


@pytest.mark.timeout(60)
def test_a_body_sent_slowly_but_within_the_deadline_is_served(api_url):
    port = api_url
    body = b'{"csv": "x"}'
    conn = socket.create_connection(("127.0.0.1", port), timeout=10)
    conn.sendall(b"POST /v1/courses/l03/roster HTTP/1.1\r\nHost: grader\r\nContent-Type: application/json\r\n"
                 b"Content-Length: " + str(len(body)).encode() + b"\r\nConnection: close\r\n\r\n")
    for byte in body:  # a byte at a time, well within the deadline
        conn.sendall(bytes([byte]))
        time.sleep(0.05)
    status, _, text = answer(conn)
    assert status == 401, text  # reached the app, which asks who is calling
