"""The one way the server fetches a URL (an LTI platform's key set, token endpoint, gradebook and roster, and any
later one): `session()`, a requests Session under one policy, and `url_refusal`, the same policy for a URL about to
be saved.

The policy: https only (plain http where settings.outbound_allow_http says so); the address a connection goes to
must be public: the host is resolved once, every address it gave is checked, and the socket connects to a checked
address itself (so a name that resolves to a public address when saved and to 127.0.0.1 when fetched, DNS rebinding,
is refused at connection time); loopback, private, shared (100.64/10), link-local, multicast, reserved and
unspecified ranges are refused, IPv4 and IPv6 alike, including IPv4 inside IPv6 (mapped, 6to4, Teredo). An operator's
allow-list (settings.outbound_allowed_hosts: host names, addresses or networks, each optionally with :port) lets a
platform inside a private network through. Redirects are not followed (a 3xx is a refusal naming its status),
proxies and .netrc of the environment are not used, the body is read as a stream and stopped past
settings.outbound_max_bytes, and the whole exchange (connection, TLS, request, headers, body) ends within
settings.outbound_timeout_s however slowly the other side sends: urllib3's timeouts bound each socket operation only
(its Timeout(total=) too: what is left is again a bound for each read), so a peer sending a byte a second never trips
them; a watchdog timer per fetch shuts down the fetch's sockets when the time is up (`_Deadline`). Name resolution is
left to the system resolver's own timeouts.

A failure is an `OutboundError` whose message is ours: the URL and the rule or the HTTP status, never the remote
body, so a caller may store or show it.

Why no library: `advocate` (the known requests wrapper for this) is unmaintained and pins old urllib3 internals; the
check here is a urllib3 connection class over `ipaddress`, about a hundred lines, and sits exactly where the socket
is opened.
"""

from __future__ import annotations

import ipaddress
import logging
import socket
import threading
import time
from functools import lru_cache
from urllib.parse import urlsplit

import requests
from requests.adapters import HTTPAdapter
from urllib3.connection import HTTPConnection, HTTPSConnection
from urllib3.connectionpool import HTTPConnectionPool, HTTPSConnectionPool
from urllib3.exceptions import ConnectTimeoutError, NameResolutionError, NewConnectionError
from urllib3.util.timeout import _DEFAULT_TIMEOUT

from grader.core.settings import settings

__all__ = ["OutboundError", "session", "url_refusal", "address_refusal"]

IPAddress = ipaddress.IPv4Address | ipaddress.IPv6Address
log = logging.getLogger(__name__)
_SHARED = ipaddress.ip_network("100.64.0.0/10")  # carrier-grade NAT: neither private nor global


class OutboundError(requests.RequestException):
    """A fetch refused by the policy or failed: the message names the URL and the rule or status, nothing the remote
    side sent."""


class _AddressRefused(Exception):
    """Raised inside urllib3 at connection time; deliberately no OSError, so urllib3 neither retries nor wraps it."""


# --- the policy ----------------------------------------------------------------------------------------------------

def _why(ip: IPAddress) -> str | None:
    """What kind of address `ip` is ("a loopback address") when it is not a public one, else None."""
    if ip.version == 6:
        teredo = ip.teredo
        for inner in (ip.ipv4_mapped, ip.sixtofour, teredo[1] if teredo else None):
            if inner is not None:
                why = _why(inner)
                return f"{why or 'an IPv4 address'} inside IPv6 ({inner})"
    for kind, flag in (("an unspecified", ip.is_unspecified), ("a loopback", ip.is_loopback),
                       ("a link-local", ip.is_link_local), ("a multicast", ip.is_multicast),
                       ("a private", ip.is_private),
                       ("a shared (carrier-grade NAT)", ip.version == 4 and ip in _SHARED),
                       ("a reserved", ip.is_reserved), ("a non-global", not ip.is_global)):
        if flag:
            return f"{kind} address"
    return None


def _entry(text: str) -> tuple[str, int | None]:
    """An allow-list entry as (host, address or network; port or None)."""
    text = text.strip()
    if text.startswith("["):  # [v6]:port or [v6/len]:port
        inside, _, rest = text[1:].partition("]")
        return inside, int(rest[1:]) if rest.startswith(":") else None
    if text.count(":") == 1:
        host, _, port = text.partition(":")
        return host, int(port)
    return text, None


@lru_cache(maxsize=8)
def _allow_list(entries: tuple[str, ...]) -> tuple[tuple[object, int | None], ...]:
    """The parsed allow-list. An entry that is no host, address or network[:port] allows nothing (the policy fails
    closed) and is logged once."""
    out = []
    for text in entries:
        try:
            host, port = _entry(text)
        except ValueError:
            log.warning("OUTBOUND_ALLOWED_HOSTS: %r is no host, address or network[:port]; it allows nothing", text)
            continue
        try:
            target: object = ipaddress.ip_network(host, strict=False)
        except ValueError:
            target = host.lower().rstrip(".")
        out.append((target, port))
    return tuple(out)


def _allowed(host: str, ip: IPAddress | None, port: int) -> bool:
    """Whether the operator's allow-list names this host (by name) or address, on this port."""
    name = host.lower().rstrip(".").strip("[]")
    for target, allowed_port in _allow_list(tuple(settings.outbound_allowed_hosts)):
        if allowed_port is not None and allowed_port != port:
            continue
        if isinstance(target, str) and target == name:
            return True
        if ip is not None and not isinstance(target, str) and ip.version == target.version and ip in target:
            return True
    return False


def address_refusal(host: str, ip: IPAddress, port: int) -> str | None:
    """Why connecting to `ip` (an address of `host`) on `port` is refused, or None when it is allowed."""
    if _allowed(host, ip, port):
        return None
    why = _why(ip)
    if why is None:
        return None
    named = host.strip("[]") if _literal(host) is not None else f"{host} resolves to {ip}, which"
    return f"{named} is {why}: only public addresses are fetched (or those the operator allows)"


def _port(parts) -> int:
    try:
        return parts.port or (443 if parts.scheme == "https" else 80)
    except ValueError:
        return -1


def _literal(host: str) -> IPAddress | None:
    try:
        return ipaddress.ip_address(host.strip("[]"))
    except ValueError:
        return None


def url_refusal(url: str, *, resolve: bool = True) -> str | None:
    """Why the policy refuses `url`, in words for its owner (None: allowed as far as can be told now). With
    `resolve`, the host's addresses are looked up and checked too; a name that does not resolve now is not refused
    here (a connection checks again)."""
    parts = urlsplit(url or "")
    if parts.scheme not in ("http", "https") or not parts.hostname:
        return "must be an absolute https URL"
    if parts.scheme == "http" and not settings.outbound_allow_http:
        return "must be an https URL (plain http is refused unless the operator allows it: OUTBOUND_ALLOW_HTTP)"
    if parts.username is not None or parts.password is not None:
        return "must not carry a user name or password"
    port = _port(parts)
    if port < 0:
        return "names no valid port"
    host = parts.hostname
    literal = _literal(host)
    if literal is not None:
        return address_refusal(host, literal, port)
    if _allowed(host, None, port):
        return None
    if host.lower().rstrip(".") == "localhost" or host.lower().endswith(".localhost"):
        return f"{host} is a loopback name: only public addresses are fetched"
    if resolve:
        try:
            infos = socket.getaddrinfo(host, port, type=socket.SOCK_STREAM)
        except (OSError, ValueError):  # no such name now, or not a name at all: a connection checks again
            return None
        for info in infos:
            refusal = address_refusal(host, ipaddress.ip_address(info[4][0].split("%")[0]), port)
            if refusal:
                return refusal
    return None


# --- the deadline: one for the whole exchange, however slowly the peer sends ----------------------------------------

class _Deadline:
    """The time one fetch has (`seconds` from now), enforced by a watchdog: every socket the fetch connects or reuses
    is watched (a duplicate of its descriptor, so the watchdog never touches a descriptor number closed and reused
    meanwhile), and when the time is up they are shut down, which ends a blocked TLS handshake, send or read at once
    (it sees the connection end); a connect gets what is left as its timeout. Used as a context manager around the
    fetch; `passed` says whether the time ran out, so that a cut-off exchange is never taken for a complete one."""

    _current = threading.local()

    def __init__(self, seconds: float):
        self.ends = time.monotonic() + seconds
        self.passed = False
        self._lock = threading.Lock()
        self._watched: list[socket.socket] = []
        self._timer = threading.Timer(seconds, self._expire)
        self._timer.daemon = True

    @classmethod
    def current(cls) -> _Deadline | None:
        """The deadline of the fetch running in this thread, if any."""
        return getattr(cls._current, "deadline", None)

    def left(self) -> float:
        return max(0.0, self.ends - time.monotonic())

    def watch(self, sock: socket.socket) -> None:
        copy = socket.socket(fileno=socket.dup(sock.fileno()))
        with self._lock:
            self._watched.append(copy)
            if self.passed:
                self._shut(copy)

    @staticmethod
    def _shut(sock: socket.socket) -> None:
        try:
            sock.shutdown(socket.SHUT_RDWR)
        except OSError:  # not connected (yet, or any more)
            pass

    def _expire(self) -> None:
        with self._lock:
            self.passed = True
            for sock in self._watched:
                self._shut(sock)

    def __enter__(self) -> _Deadline:
        self._outer = self.current()
        self._current.deadline = self
        self._timer.start()
        return self

    def __exit__(self, *exc) -> None:
        self._timer.cancel()
        self._current.deadline = self._outer
        with self._lock:
            for sock in self._watched:
                sock.close()  # the duplicate only: a kept-alive connection stays open for the next fetch
            self._watched.clear()


# --- the connection: resolve once, check, connect to the checked address -------------------------------------------

def _connect(conn: HTTPConnection):
    host, port = conn._dns_host, conn.port
    try:
        infos = socket.getaddrinfo(host, port, type=socket.SOCK_STREAM)
    except socket.gaierror as exc:
        raise NameResolutionError(conn.host, conn, exc) from exc
    last: OSError | None = None
    deadline = _Deadline.current()
    for family, kind, proto, _, address in infos:
        refusal = address_refusal(conn.host, ipaddress.ip_address(address[0].split("%")[0]), port)
        if refusal:
            raise _AddressRefused(refusal)
    for family, kind, proto, _, address in infos:
        left = deadline.left() if deadline is not None else None  # each address tried gets what is left, no more
        if left is not None and left <= 0:
            raise ConnectTimeoutError(conn, f"Connection to {conn.host} timed out")
        sock = socket.socket(family, kind, proto)
        try:
            for option in conn.socket_options or ():
                sock.setsockopt(*option)
            if conn.timeout is not _DEFAULT_TIMEOUT:
                sock.settimeout(conn.timeout)
            if left is not None:
                sock.settimeout(left if sock.gettimeout() is None else min(left, sock.gettimeout()))
                deadline.watch(sock)
                conn._watched_by = deadline
            if conn.source_address:
                sock.bind(conn.source_address)
            sock.connect(address)  # the very address checked above: no second lookup
            return sock
        except socket.timeout as exc:
            sock.close()
            raise ConnectTimeoutError(conn, f"Connection to {conn.host} timed out") from exc
        except OSError as exc:
            sock.close()
            last = exc
    raise NewConnectionError(conn, f"Failed to establish a new connection: {last}")


class _Watched:
    """A connection whose socket the running fetch's deadline watches, a kept-alive one reused by a later fetch of
    the session too."""

    _watched_by: _Deadline | None = None

    def request(self, *args, **kwargs):
        deadline = _Deadline.current()
        if deadline is not None and self.sock is not None and self._watched_by is not deadline:
            deadline.watch(self.sock)
            self._watched_by = deadline
        return super().request(*args, **kwargs)


class _GuardedHTTPConnection(_Watched, HTTPConnection):
    def _new_conn(self):
        return _connect(self)


class _GuardedHTTPSConnection(_Watched, HTTPSConnection):
    def _new_conn(self):  # TLS is wrapped around this socket by urllib3 with the URL's host name (SNI, certificate)
        return _connect(self)


class _HTTPPool(HTTPConnectionPool):
    ConnectionCls = _GuardedHTTPConnection


class _HTTPSPool(HTTPSConnectionPool):
    ConnectionCls = _GuardedHTTPSConnection


class _GuardedAdapter(HTTPAdapter):
    def init_poolmanager(self, *args, **kwargs):
        super().init_poolmanager(*args, **kwargs)
        self.poolmanager.pool_classes_by_scheme = {"http": _HTTPPool, "https": _HTTPSPool}

    def proxy_manager_for(self, *args, **kwargs):
        raise _AddressRefused("a proxy would hide the address connected to")


class _Session(requests.Session):
    """requests under the policy: see the module's docstring."""

    def __init__(self):
        super().__init__()
        self.trust_env = False  # no proxy or .netrc from the environment: the guard checks where it connects
        adapter = _GuardedAdapter(max_retries=0)
        self.mount("http://", adapter)
        self.mount("https://", adapter)
        self.headers["User-Agent"] = "grader (LTI tool)"

    def request(self, method, url, **kwargs):
        refusal = url_refusal(url, resolve=False)  # the addresses are checked when the connection opens
        if refusal:
            raise OutboundError(f"{url}: {refusal}")
        limit, cap = settings.outbound_timeout_s, settings.outbound_max_bytes
        kwargs.update(allow_redirects=False, stream=True, timeout=(limit, limit), proxies={})
        no_answer = OutboundError(f"{url}: no answer within {limit:g} s")
        with _Deadline(limit) as deadline:
            try:
                response = super().request(method, url, **kwargs)
            except _AddressRefused as exc:
                raise OutboundError(f"{url}: refused: {exc}") from None
            except requests.Timeout:
                raise no_answer from None
            except requests.RequestException:
                raise (no_answer if deadline.passed else OutboundError(f"{url}: could not connect")) from None
            with response:
                if deadline.passed:  # headers cut off by the watchdog end early and may look complete
                    raise no_answer
                if response.is_redirect or 300 <= response.status_code < 400:
                    raise OutboundError(f"{url} answered HTTP {response.status_code} (a redirect): redirects are not "
                                        "followed")
                declared = response.headers.get("Content-Length", "")
                if declared.isdigit() and int(declared) > cap:
                    raise OutboundError(f"{url} answered HTTP {response.status_code} with more than {cap} bytes")
                took_longer = OutboundError(f"{url}: the answer took longer than {limit:g} s")
                body, size = [], 0
                try:
                    for chunk in response.iter_content(65536):
                        size += len(chunk)
                        if size > cap:
                            raise OutboundError(f"{url} answered HTTP {response.status_code} with more than {cap} "
                                                "bytes")
                        if deadline.passed:
                            raise took_longer
                        body.append(chunk)
                except requests.RequestException as exc:
                    if isinstance(exc, OutboundError):
                        raise
                    raise (took_longer if deadline.passed else
                           OutboundError(f"{url}: the answer broke off (HTTP {response.status_code})")) from None
                if deadline.passed:  # a body that ends with the connection, cut by the watchdog, looks complete
                    raise took_longer
        response._content = b"".join(body)
        return response


def session() -> requests.Session:
    """A requests Session under the policy, for one piece of work (pylti1p3 takes it as `requests_session`)."""
    return _Session()
