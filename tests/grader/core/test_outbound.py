"""The server fetches nothing internal (grader.core.outbound): the review's high finding replayed (an instructor's
registration naming an internal server, an anonymous login and an unsigned launch), refused when the registration is
saved and, with that check bypassed in the database, when the launch fetches; and the guard itself against real
servers on loopback: addresses checked where the socket connects (DNS rebinding, a name with a public and a private
address), the operator's allow-list by port and exact name, no redirects, a size cap (declared or counted over small
chunks), one deadline for the whole exchange however slowly a peer sends, https only, the URL's rules again at fetch
time."""

from __future__ import annotations

import base64
import html
import json
import re
import socket
import threading
import time
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from urllib.parse import parse_qs, urlsplit

import pytest
from sqlalchemy import select

from tests.grader.services.lti.test_lti import _session

SECRET = "internal-secret-7f3a9c"


class Internal:
    """A server inside the network (on loopback): it answers SECRET and records every request it gets. `redirect`
    makes it answer 302 to that URL; `size` pads the answer to that many bytes; `stall` holds the answer back."""

    def __init__(self, *, redirect: str | None = None, size: int = 0, stall: threading.Event | None = None):
        self.seen: list[str] = []
        internal = self

        class Handler(BaseHTTPRequestHandler):
            def _answer(self):
                internal.seen.append(self.path)
                if stall is not None:
                    stall.wait(30)
                if redirect:
                    self.send_response(302)
                    self.send_header("Location", redirect)
                    self.end_headers()
                    return
                body = (f"{SECRET} " + "x" * max(0, size)).encode()
                self.send_response(200)
                self.send_header("Content-Type", "text/plain")
                self.send_header("Content-Length", str(len(body)))
                self.end_headers()
                self.wfile.write(body)

            do_GET = do_POST = _answer

            def log_message(self, *args):
                pass

        self.server = ThreadingHTTPServer(("127.0.0.1", 0), Handler)
        self.port = self.server.server_port
        self.url = f"http://127.0.0.1:{self.port}/internal/secret"
        threading.Thread(target=self.server.serve_forever, daemon=True).start()

    def close(self):
        self.server.shutdown()
        self.server.server_close()


class Peer:
    """A peer on loopback that sends its answer slowly (a thread with a listening socket): to each connection, after
    the request, `pieces[0]` at once, then each other piece `pace` seconds after the last; at `stop_after` seconds
    whatever remains at once, then it closes (the test's own bound: a client that waits for it all is done then)."""

    def __init__(self, pieces: list[bytes], *, pace: float, stop_after: float = 7.0):
        self.listener = socket.create_server(("127.0.0.1", 0))
        self.listener.settimeout(0.2)
        self.port = self.listener.getsockname()[1]
        self.url = f"http://127.0.0.1:{self.port}/keys"
        self.closed = False
        threading.Thread(target=self._serve, args=(pieces, pace, stop_after), daemon=True).start()

    def _serve(self, pieces: list[bytes], pace: float, stop_after: float):
        while not self.closed:
            try:
                conn, _ = self.listener.accept()
            except TimeoutError:
                continue
            except OSError:
                return
            threading.Thread(target=self._send, args=(conn, pieces, pace, stop_after), daemon=True).start()

    @staticmethod
    def _send(conn: socket.socket, pieces: list[bytes], pace: float, stop_after: float):
        end = time.monotonic() + stop_after
        with conn:
            try:
                conn.recv(65536)  # the request
                for i, piece in enumerate(pieces):
                    if i and pace:
                        if time.monotonic() + pace > end:
                            conn.sendall(b"".join(pieces[i:]))
                            return
                        time.sleep(pace)
                    conn.sendall(piece)
            except OSError:  # the client went away
                pass

    def close(self):
        self.closed = True
        self.listener.close()


def _key_set_answer(body: bytes) -> bytes:
    return (b"HTTP/1.1 200 OK\r\nContent-Type: application/json\r\nContent-Length: " + str(len(body)).encode()
            + b"\r\n\r\n" + body)


@pytest.fixture
def peers():
    made: list[Peer] = []
    yield lambda pieces, **kw: made.append(Peer(pieces, **kw)) or made[-1]
    for peer in made:
        peer.close()


@pytest.fixture
def internal():
    server = Internal()
    yield server
    server.close()


@pytest.fixture
def http_allowed(monkeypatch):
    """The operator allows plain http (as the tests on loopback need), nothing else: no allow-list."""
    from grader.core.settings import settings

    monkeypatch.setattr(settings, "outbound_allow_http", True)
    monkeypatch.setattr(settings, "outbound_allowed_hosts", [])
    return settings


def _registration_body(url: str) -> dict:
    return {"issuer": "https://lms.example.edu", "client_id": "ssrf-1", "deployment_ids": ["1"],
            "auth_login_url": "https://lms.example.edu/auth", "auth_token_url": url, "key_set_url": url}


def _register(api, client_id: str, key_set_url: str):
    """An instructor registers a platform whose key set is at `key_set_url` (the token URL is a public one)."""
    return api.client.post("/v1/courses/l03/lti/registrations", headers=api.as_("prof"),
                           json=_registration_body("https://lms.example.edu/token")
                           | {"client_id": client_id, "key_set_url": key_set_url})


def test_an_instructor_cannot_register_an_internal_key_set_url(api, internal, http_allowed):
    answer = api.client.post("/v1/courses/l03/lti/registrations", headers=api.as_("prof"),
                             json=_registration_body(internal.url))
    assert answer.status_code == 422, answer.text
    fields = {e["field"]: e["rule"] for e in answer.json()["errors"]}
    assert set(fields) == {"key_set_url", "auth_token_url"}
    assert "127.0.0.1 is a loopback address" in fields["key_set_url"]
    for address in ("http://localhost:1/x", "http://[::1]/x", "http://[::ffff:127.0.0.1]/x", "http://10.0.0.5/x",
                    "http://169.254.169.254/latest/meta-data", "http://0.0.0.0/x", "http://192.168.1.1/x"):
        refused = api.client.post("/v1/courses/l03/lti/registrations", headers=api.as_("prof"),
                                  json=_registration_body("https://lms.example.edu/jwks") | {"key_set_url": address})
        assert refused.status_code == 422 and refused.json()["errors"][0]["field"] == "key_set_url", address
    assert internal.seen == []
    assert api.client.get("/v1/courses/l03/lti/registrations", headers=api.as_("prof")).json() == []


def test_plain_http_is_refused_unless_the_operator_allows_it(api):
    answer = api.client.post("/v1/courses/l03/lti/registrations", headers=api.as_("prof"),
                             json=_registration_body("https://lms.example.edu/jwks")
                             | {"key_set_url": "http://lms.example.edu/jwks"})
    assert answer.status_code == 422
    assert answer.json()["errors"] == [{"field": "key_set_url", "rule": "must be an https URL (plain http is refused "
                                        "unless the operator allows it: OUTBOUND_ALLOW_HTTP)"}]


def _unsigned(claims: dict) -> str:
    part = lambda d: base64.urlsafe_b64encode(json.dumps(d).encode()).decode().rstrip("=")  # noqa: E731
    return f"{part({'alg': 'RS256', 'kid': 'k1', 'typ': 'JWT'})}.{part(claims)}.AAAA"


def _launch(api, client_id: str):
    """An anonymous login and an unsigned launch for the registration of `client_id`: the launch fetches its key set
    (the launch's answer)."""
    login = api.client.get("/lti/login", params={"iss": "https://lms.example.edu", "client_id": client_id,
                                                 "login_hint": "x", "target_link_uri": "http://testserver/lti/launch"},
                           follow_redirects=False)
    assert login.status_code == 302, login.text
    query = parse_qs(urlsplit(login.headers["location"]).query)
    now = int(time.time())
    token = _unsigned({"iss": "https://lms.example.edu", "aud": client_id, "sub": "u", "nonce": query["nonce"][0],
                       "iat": now, "exp": now + 300,
                       "https://purl.imsglobal.org/spec/lti/claim/deployment_id": "1"})
    return api.client.post("/lti/launch", data={"id_token": token, "state": query["state"][0]},
                           follow_redirects=False)


def _key_set_refusal(answer) -> str:
    """The rule the launch's error page gives for key_set_url."""
    assert answer.status_code == 400, answer.text
    found = re.search(r"<li><code>key_set_url</code>: (.*?)</li>", answer.text)
    assert found, answer.text
    return html.unescape(found.group(1))


def test_a_launch_never_fetches_an_internal_key_set_url_stored_past_the_check(api, internal, http_allowed):
    """The finding as the review ran it, with the registration's check bypassed (a row written to the database
    directly): an anonymous login and an unsigned launch make the tool fetch the key set, which must be refused at
    fetch time, and the page must not show what the internal server would have said."""
    from grader.core.models import Course, LtiDeployment, LtiRegistration

    with _session() as session:
        course = session.scalar(select(Course).where(Course.name == "l03"))
        row = LtiRegistration(course_id=course.id, issuer="https://lms.example.edu", client_id="ssrf-1",
                              auth_login_url="https://lms.example.edu/auth", auth_token_url=internal.url,
                              key_set_url=internal.url)
        session.add(row)
        session.flush()
        session.add(LtiDeployment(registration_id=row.id, deployment_id="1"))
        session.commit()
    answer = _launch(api, "ssrf-1")
    assert answer.status_code == 400, answer.text
    assert SECRET not in answer.text
    assert "<code>key_set_url</code>" in answer.text and "127.0.0.1 is a loopback address" in answer.text
    assert internal.seen == []  # refused before a connection: the internal server got no request


def test_token_and_service_urls_stored_past_the_check_are_refused_when_fetched(api, internal, http_allowed):
    """The registration's token URL and a launch's service URLs (gradebook, roster) naming the internal server, as
    rows written around the checks: sending scores and syncing the roster fetch nothing and show no body."""
    from grader.core.models import Course, LtiContext, LtiIdentity, LtiRegistration, User
    from tests.grader.services.setup.test_assignments import create
    from tests.grader.services.lti.test_lti import graded_attempt

    aid = create(api).json()["id"]
    with _session() as session:
        course = session.scalar(select(Course).where(Course.name == "l03"))
        row = LtiRegistration(course_id=course.id, issuer="https://lms.example.edu", client_id="ssrf-2",
                              auth_login_url="https://lms.example.edu/auth", auth_token_url=internal.url,
                              key_set_url="https://lms.example.edu/jwks")
        session.add(row)
        session.flush()
        session.add(LtiContext(registration_id=row.id, context_id="ctx", lineitems_url=internal.url,
                               memberships_url=internal.url,
                               scopes=[f"https://purl.imsglobal.org/spec/lti-ags/scope/{name}"
                                       for name in ("lineitem", "score")]))
        alice = session.scalar(select(User).where(User.name == "alice", User.course_id == course.id))
        session.add(LtiIdentity(registration_id=row.id, sub="lms-alice", user_id=alice.id))
        session.commit()
    graded_attempt(aid, "lms-alice", 1, 5.0)
    sent = api.client.post(f"/v1/courses/l03/lti/assignments/{aid}/scores", headers=api.as_("prof"))
    assert sent.status_code == 200 and SECRET not in sent.text
    (score,) = sent.json()
    assert score["status"] == "failed" and "127.0.0.1 is a loopback address" in score["error"]
    roster = api.client.post("/v1/courses/l03/lti/roster-sync", headers=api.as_("prof"))
    assert roster.status_code == 409 and SECRET not in roster.text and "loopback" in roster.json()["detail"]
    assert internal.seen == []


# --- the guard itself ------------------------------------------------------------------------------------------------

def _fetch(url: str):
    from grader.core import outbound

    return outbound.session().get(url)


def _refusal(url: str) -> str:
    from grader.core.outbound import OutboundError

    with pytest.raises(OutboundError) as caught:
        _fetch(url)
    assert SECRET not in str(caught.value)
    return str(caught.value)


@pytest.fixture
def rebinding(monkeypatch):
    """A name whose DNS answer changes between the check at save and the connection (DNS rebinding): a public address
    first, then loopback. `answers` lists what each lookup returned."""
    real = socket.getaddrinfo
    answers: list[str] = []

    def lookup(host, port, *args, **kwargs):
        if host != "rebind.example.edu":
            return real(host, port, *args, **kwargs)
        address = "93.184.216.34" if not answers else "127.0.0.1"
        answers.append(address)
        return [(socket.AF_INET, socket.SOCK_STREAM, 6, "", (address, port))]

    monkeypatch.setattr(socket, "getaddrinfo", lookup)
    return answers


def test_the_address_is_checked_where_the_socket_connects_so_dns_rebinding_is_refused(internal, http_allowed,
                                                                                       rebinding):
    from grader.core import outbound

    url = f"http://rebind.example.edu:{internal.port}/internal/secret"
    assert outbound.url_refusal(url) is None  # at save it resolved to a public address
    message = _refusal(url)
    assert rebinding == ["93.184.216.34", "127.0.0.1"]
    assert message == (f"{url}: refused: rebind.example.edu resolves to 127.0.0.1, which is a loopback address: "
                       "only public addresses are fetched (or those the operator allows)")
    assert internal.seen == []


def test_the_allow_list_lets_one_port_through_and_no_other(internal, http_allowed):
    other = Internal()
    try:
        http_allowed.outbound_allowed_hosts = [f"127.0.0.1:{internal.port}"]
        assert _fetch(internal.url).text.startswith(SECRET)
        assert "loopback" in _refusal(other.url) and other.seen == []
        http_allowed.outbound_allowed_hosts = ["127.0.0.0/8"]
        assert _fetch(other.url).status_code == 200
    finally:
        other.close()


def test_a_redirect_is_not_followed(internal, http_allowed):
    hop = Internal(redirect=internal.url)
    try:
        http_allowed.outbound_allowed_hosts = [f"127.0.0.1:{hop.port}"]
        assert _refusal(hop.url) == f"{hop.url} answered HTTP 302 (a redirect): redirects are not followed"
        assert len(hop.seen) == 1 and internal.seen == []
    finally:
        hop.close()


def test_an_answer_past_the_size_cap_is_stopped(http_allowed):
    big = Internal(size=5_000)
    try:
        http_allowed.outbound_allowed_hosts = [f"127.0.0.1:{big.port}"]
        http_allowed.outbound_max_bytes = 1_000
        assert _refusal(big.url) == f"{big.url} answered HTTP 200 with more than 1000 bytes"
    finally:
        big.close()


def test_an_answer_that_does_not_come_is_given_up(http_allowed):
    stall = threading.Event()
    slow = Internal(stall=stall)
    try:
        http_allowed.outbound_allowed_hosts = [f"127.0.0.1:{slow.port}"]
        http_allowed.outbound_timeout_s = 0.5
        assert _refusal(slow.url) == f"{slow.url}: no answer within 0.5 s"
    finally:
        stall.set()
        slow.close()


@pytest.mark.parametrize("address", ["127.0.0.1", "10.1.2.3", "172.16.0.1", "192.168.0.1", "169.254.169.254",
                                     "100.64.0.1", "0.0.0.0", "224.0.0.1", "240.0.0.1", "255.255.255.255", "::1", "::",
                                     "fe80::1", "fc00::1", "ff02::1", "::ffff:127.0.0.1", "::ffff:10.0.0.1",
                                     "2002:7f00:1::1", "64:ff9b::7f00:1"])
def test_every_non_public_address_is_refused(http_allowed, address):
    import ipaddress

    from grader.core.outbound import address_refusal

    assert address_refusal("h", ipaddress.ip_address(address), 443) is not None


@pytest.mark.parametrize("address", ["93.184.216.34", "1.1.1.1", "2606:4700:4700::1111"])
def test_public_addresses_pass(http_allowed, address):
    import ipaddress

    from grader.core.outbound import address_refusal

    assert address_refusal("h", ipaddress.ip_address(address), 443) is None


def _certificate(tmp_path, name: str):
    """A self-signed certificate for `name` and its key, as files."""
    import datetime

    from cryptography import x509
    from cryptography.hazmat.primitives import hashes, serialization
    from cryptography.hazmat.primitives.asymmetric import ec
    from cryptography.x509.oid import NameOID

    key = ec.generate_private_key(ec.SECP256R1())
    subject = x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, name)])
    start = datetime.datetime.now(datetime.UTC) - datetime.timedelta(hours=1)
    cert = (x509.CertificateBuilder().subject_name(subject).issuer_name(subject).public_key(key.public_key())
            .serial_number(x509.random_serial_number()).not_valid_before(start)
            .not_valid_after(start + datetime.timedelta(days=1))
            .add_extension(x509.SubjectAlternativeName([x509.DNSName(name)]), critical=False)
            .add_extension(x509.BasicConstraints(ca=True, path_length=None), critical=True)
            .sign(key, hashes.SHA256()))
    cert_file, key_file = tmp_path / f"{name}.pem", tmp_path / f"{name}.key"
    cert_file.write_bytes(cert.public_bytes(serialization.Encoding.PEM))
    key_file.write_bytes(key.private_bytes(serialization.Encoding.PEM, serialization.PrivateFormat.PKCS8,
                                           serialization.NoEncryption()))
    return cert_file, key_file


def test_https_is_verified_against_the_urls_host_name_on_the_checked_socket(tmp_path, monkeypatch):
    """The guard opens the socket to the checked address; TLS over it still names and verifies the URL's host (a
    platform on a private network, allowed by name, resolved here to loopback)."""
    import ssl

    from grader.core import outbound
    from grader.core.settings import settings

    server = Internal()
    cert, key = _certificate(tmp_path, "lms.campus.example")
    context = ssl.SSLContext(ssl.PROTOCOL_TLS_SERVER)
    context.load_cert_chain(cert, key)
    server.server.socket = context.wrap_socket(server.server.socket, server_side=True)
    real = socket.getaddrinfo

    def lookup(host, port, *args, **kwargs):
        if host in ("lms.campus.example", "other.campus.example"):
            return [(socket.AF_INET, socket.SOCK_STREAM, 6, "", ("127.0.0.1", port))]
        return real(host, port, *args, **kwargs)

    monkeypatch.setattr(socket, "getaddrinfo", lookup)
    monkeypatch.setattr(settings, "outbound_allowed_hosts", [f"lms.campus.example:{server.port}",
                                                             f"other.campus.example:{server.port}"])
    try:
        answer = outbound.session().get(f"https://lms.campus.example:{server.port}/keys", verify=str(cert))
        assert answer.status_code == 200 and answer.text.startswith(SECRET)
        with pytest.raises(outbound.OutboundError, match="could not connect"):  # the certificate names another host
            outbound.session().get(f"https://other.campus.example:{server.port}/keys", verify=str(cert))
        assert "loopback" in _refusal(f"https://127.0.0.1:{server.port}/keys")  # not allowed by address
    finally:
        server.close()


# --- one deadline for the whole exchange (issue 44, finding 1) ---------------------------------------------------------

@pytest.fixture
def two_seconds(http_allowed):
    """Plain http to loopback on any port (the peers' ports are not known before), and 2 s for a whole fetch."""
    http_allowed.outbound_allowed_hosts = ["127.0.0.1"]
    http_allowed.outbound_timeout_s = 2.0
    return http_allowed


def test_headers_sent_a_line_a_second_are_cut_at_the_deadline(two_seconds, peers):
    """Each read gets a line within the per-read timeout; the whole fetch still ends at its deadline."""
    lines = [b"HTTP/1.1 200 OK\r\n", *(f"X-Drip-{i}: {i}\r\n".encode() for i in range(20))]
    peer = peers([*lines, _key_set_answer(b'{"keys": []}').partition(b"\r\n")[2]], pace=1.0)
    started = time.monotonic()
    message = _refusal(peer.url)
    assert time.monotonic() - started < 3.0
    assert message == f"{peer.url}: no answer within 2 s"


def test_a_launch_is_not_held_by_a_key_set_sent_a_byte_a_second(api, two_seconds, peers):
    """The finding as it meets a user: an instructor registers a platform whose key set drips (a Content-Length body,
    a byte a second); an anonymous launch fetches it and is answered at the deadline, naming it."""
    answer = _key_set_answer(b'{"keys": []}' + b" " * 30)
    head, _, body = answer.partition(b"\r\n\r\n")
    peer = peers([head + b"\r\n\r\n", *(body[i:i + 1] for i in range(len(body)))], pace=1.0)
    assert _register(api, "drip-1", peer.url).status_code == 201
    started = time.monotonic()
    launched = _launch(api, "drip-1")
    assert time.monotonic() - started < 3.0
    assert _key_set_refusal(launched) == f"{peer.url}: the answer took longer than 2 s"


# --- the guard's single lines that no test held (issue 50: OUT1, OUT2, OUT3, OUT5) ------------------------------------

@pytest.fixture
def dns(monkeypatch):
    """Names this test resolves itself: host -> its addresses, in order (other names as the system resolves them)."""
    real = socket.getaddrinfo
    names: dict[str, list[str]] = {}

    def lookup(host, port, *args, **kwargs):
        if host not in names:
            return real(host, port, *args, **kwargs)
        return [(socket.AF_INET6, socket.SOCK_STREAM, 6, "", (a, port, 0, 0)) if ":" in a else
                (socket.AF_INET, socket.SOCK_STREAM, 6, "", (a, port)) for a in names[host]]

    monkeypatch.setattr(socket, "getaddrinfo", lookup)
    return names


def test_a_name_with_a_public_and_a_private_address_is_refused_where_the_socket_connects(api, internal, http_allowed,
                                                                                          dns):
    """Registered while its name had a public address only; by the launch it has a private one too, after the public
    one: every address is checked before any is connected to."""
    http_allowed.outbound_timeout_s = 2.0
    dns["two.example.edu"] = ["2606:4700:4700::1111"]
    url = f"http://two.example.edu:{internal.port}/internal/secret"
    assert _register(api, "two-1", url).status_code == 201
    dns["two.example.edu"] = ["2606:4700:4700::1111", "127.0.0.1"]
    assert _key_set_refusal(_launch(api, "two-1")) == (
        f"{url}: refused: two.example.edu resolves to 127.0.0.1, which is a loopback address: only public addresses "
        "are fetched (or those the operator allows)")
    assert internal.seen == []


def test_the_allow_list_names_a_host_exactly_not_every_name_ending_in_it(api, dns, monkeypatch):
    from grader.core.settings import settings

    dns["lms.campus.internal"] = dns["evil-lms.campus.internal"] = ["10.0.0.7"]
    monkeypatch.setattr(settings, "outbound_allowed_hosts", ["lms.campus.internal"])
    assert _register(api, "campus-1", "https://lms.campus.internal/jwks").status_code == 201
    refused = _register(api, "campus-2", "https://evil-lms.campus.internal/jwks")
    assert refused.status_code == 422
    assert refused.json()["errors"] == [{"field": "key_set_url", "rule": (
        "evil-lms.campus.internal resolves to 10.0.0.7, which is a private address: only public addresses are "
        "fetched (or those the operator allows)")}]


def test_an_answer_past_the_size_cap_in_small_chunks_is_stopped(api, two_seconds, peers):
    """No Content-Length to refuse at once: a chunked key set of 3,000 bytes in 500-byte chunks, counted as it comes."""
    two_seconds.outbound_max_bytes = 1_000
    body = b'{"keys": []}' + b" " * 2_988
    chunks = [b"%x\r\n%s\r\n" % (500, body[i:i + 500]) for i in range(0, len(body), 500)]
    peer = peers([b"HTTP/1.1 200 OK\r\nContent-Type: application/json\r\nTransfer-Encoding: chunked\r\n\r\n",
                  *chunks, b"0\r\n\r\n"], pace=0)
    assert _register(api, "big-1", peer.url).status_code == 201
    assert _key_set_refusal(_launch(api, "big-1")) == f"{peer.url} answered HTTP 200 with more than 1000 bytes"


def test_the_urls_own_rules_apply_again_when_it_is_fetched(api, internal, http_allowed):
    """Registered while the operator allowed plain http; allowed no more, the launch fetches nothing. A user name in
    the URL, and a scheme that is no http(s), are refused at fetch time too."""
    http_allowed.outbound_allowed_hosts = [f"127.0.0.1:{internal.port}"]
    assert _register(api, "http-1", internal.url).status_code == 201
    http_allowed.outbound_allow_http = False
    assert _key_set_refusal(_launch(api, "http-1")) == (
        f"{internal.url}: must be an https URL (plain http is refused unless the operator allows it: "
        "OUTBOUND_ALLOW_HTTP)")
    http_allowed.outbound_allow_http = True
    with_user = f"http://grader:pw@127.0.0.1:{internal.port}/internal/secret"
    assert _refusal(with_user) == f"{with_user}: must not carry a user name or password"
    assert _refusal(f"ftp://127.0.0.1:{internal.port}/x") == f"ftp://127.0.0.1:{internal.port}/x: must be an " \
                                                             "absolute https URL"
    assert internal.seen == []
