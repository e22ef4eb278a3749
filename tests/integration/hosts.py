"""Two test hosts on one machine, deployed as an operator deploys two machines (issue 24, item 3).

Host A is this machine's root network namespace: PostgreSQL, Redis and the API run there. Host B is a network
namespace of its own, joined to host A by a veth pair (10.77.N.1 on A, 10.77.N.2 on B; no route anywhere else, not
even to host A's loopback), and its Celery worker runs in its own mount and UTS namespaces: hostname `twohost-b`, and
a private tmpfs mounted over its DATA_DIR, at the same path as the API's DATA_DIR (as docker-compose.yml gives both
`/data`), so a file one host writes there is invisible to the other. What host B still reads from the shared disk:
the code, the virtual environment and the rest of the filesystem (the operator's image); its Genesis kernel cache is
copied into its tmpfs when it starts (its own local cache, and `services.private_kernel_cache`'s reason: a process
this test SIGKILLs must not leave the machine's cache locked). Its log goes to a file host A opened, for the test.

PostgreSQL and Redis are private instances (tests/private_services.py) listening on host A's veth address only: the
machine's own servers listen on 127.0.0.1, which host B cannot reach and which this test must not reconfigure.
Everything here needs root (namespaces, mounts, links); `require_root` fails under CI=true and skips elsewhere.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import signal
import subprocess
import sys
import uuid
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

from tests import services

HOST_B = "twohost-b"  # host B's hostname: what its worker stamps on every run it claims (CaseRun.worker)
SUBNET_PREFIX = "10.77"


def require_root() -> None:
    """Namespaces, mounts and links need root and iproute2; without them the test cannot build its hosts."""
    missing = [tool for tool in ("ip", "unshare", "nsenter", "mount") if shutil.which(tool) is None]
    if os.geteuid() != 0 or missing:
        services.unavailable("two test hosts", PermissionError(
            f"root and ip/unshare/nsenter/mount are needed (euid {os.geteuid()}, missing {missing or 'none'})"))


def _ip(*argv: str) -> None:
    done = subprocess.run(["ip", *argv], capture_output=True, text=True)
    if done.returncode != 0:
        raise RuntimeError(f"ip {' '.join(argv)} failed: {done.stderr.strip()}")


def _free_subnet() -> str:
    """The first 10.77.N.0/24 no interface of this machine uses (a concurrent or crashed run may hold one)."""
    used = subprocess.run(["ip", "-o", "-4", "addr"], capture_output=True, text=True, check=True).stdout
    for n in range(256):
        if f" {SUBNET_PREFIX}.{n}." not in used:
            return f"{SUBNET_PREFIX}.{n}"
    raise RuntimeError(f"every {SUBNET_PREFIX}.N.0/24 is in use on this machine")


@dataclass(frozen=True)
class Link:
    """Host B's network namespace and the veth pair joining it to host A."""

    namespace: str
    address_a: str
    address_b: str


@contextlib.contextmanager
def veth_link() -> Iterator[Link]:
    """A network namespace for host B joined to the root namespace (host A) by a veth pair; deleted afterwards,
    also when building it failed half-way (deleting the namespace deletes its veth end, and with it the peer)."""
    tag = uuid.uuid4().hex[:6]
    namespace, end_a, end_b = f"twohost-{tag}", f"tha-{tag}", f"thb-{tag}"  # interface names: 15 bytes at most
    subnet = _free_subnet()
    link = Link(namespace, f"{subnet}.1", f"{subnet}.2")
    try:
        try:
            _ip("netns", "add", namespace)
        except RuntimeError as exc:  # root without CAP_SYS_ADMIN (some containers): no second host here
            services.unavailable("a network namespace", exc)
        _ip("link", "add", end_a, "type", "veth", "peer", "name", end_b, "netns", namespace)
        _ip("addr", "add", f"{link.address_a}/24", "dev", end_a)
        _ip("link", "set", end_a, "up")
        _ip("-n", namespace, "addr", "add", f"{link.address_b}/24", "dev", end_b)
        _ip("-n", namespace, "link", "set", end_b, "up")
        _ip("-n", namespace, "link", "set", "lo", "up")
        yield link
    finally:
        subprocess.run(["ip", "netns", "del", namespace], capture_output=True)
        subprocess.run(["ip", "link", "del", end_a], capture_output=True)  # gone already unless the netns never was


# Run as host B's first process: its hostname, a private tmpfs over DATA_DIR, its kernel cache, then the worker.
_HOST_B_INIT = """set -e
hostname "$1"
mount -t tmpfs -o size=2g "$1-disk" "$DATA_DIR"
if [ -d "$2" ]; then mkdir -p "$QD_OFFLINE_CACHE_FILE_PATH"; cp -r "$2/." "$QD_OFFLINE_CACHE_FILE_PATH"; fi
rm -f "$QD_OFFLINE_CACHE_FILE_PATH"/*.lock
shift 2
exec "$@"
"""


def machine_kernel_cache() -> Path:
    """This machine's quadrants kernel cache (what services.private_kernel_cache copies)."""
    return Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "quadrants" / "qdcache"


def start_worker_on_host_b(link: Link, env: dict, queues: str, log: Path) -> subprocess.Popen:
    """A Celery worker as host B's only process tree: in `link`'s network namespace, and in a new mount and UTS
    namespace, so its DATA_DIR (env's, the same path as the API's) is a fresh private tmpfs: a new host B, or one
    that rebooted and lost its disk. Returned once Celery says it is ready; its pid is the worker's main process (ip
    netns exec, unshare and sh each exec the next), and its namespaces live as long as its process tree."""
    from worker.celery_app import worker_argv  # lazy, as tools.harness.processes.start_worker: Celery on import

    data_dir = Path(env["DATA_DIR"])
    env = env | {"QD_OFFLINE_CACHE_FILE_PATH": str(data_dir / "kernel-cache")}
    command = ["ip", "netns", "exec", link.namespace, "unshare", "--mount", "--uts", "--propagation", "private",
               "--", "sh", "-c", _HOST_B_INIT, "host-b-init", HOST_B, str(machine_kernel_cache()),
               *worker_argv(queues.split(","), name=f"{queues.replace(',', '-')}-{uuid.uuid4().hex[:6]}@%h")]
    proc = subprocess.Popen(command, cwd=services.ROOT, env=env, stdout=log.open("ab"), stderr=subprocess.STDOUT,
                            start_new_session=True)
    try:
        services.wait_for(lambda: " ready." in log.read_text(errors="replace"), "celery worker on host B", proc, log)
    except BaseException:
        kill_host_b(proc)  # no half-started host B outlives the test
        raise
    return proc


def kill_host_b(worker: subprocess.Popen) -> list[int]:
    """SIGKILL every process of host B's worker (main, pool and case processes), as a host that loses power: its
    mount namespace, and with it the tmpfs, goes with the last of them. Returns the pids killed."""
    doomed = [worker.pid, *services.children(worker.pid)]
    doomed += [grandchild for pid in doomed[1:] for grandchild in services.children(pid)]
    for pid in doomed:
        with contextlib.suppress(ProcessLookupError):
            os.kill(pid, signal.SIGKILL)
    worker.wait()
    return doomed


def reaches_from_host_b(link: Link, host: str, port: int) -> bool:
    """Whether a TCP connection from host B's network namespace to host:port opens."""
    probe = f"import socket; socket.create_connection(({host!r}, {port}), timeout=3).close()"
    return subprocess.run(["ip", "netns", "exec", link.namespace, sys.executable, "-c", probe],
                          capture_output=True).returncode == 0


def files_on_host_b(worker: subprocess.Popen, folder: Path) -> list[str]:
    """The files under `folder` as host B sees it (entering the mount namespace of its running worker), relative."""
    done = subprocess.run(["nsenter", "--target", str(worker.pid), "--mount", "--", "find", str(folder), "-type", "f"],
                          capture_output=True, text=True, check=True)
    return sorted(str(Path(line).relative_to(folder)) for line in done.stdout.splitlines())


def files_on_host_a(folder: Path) -> list[str]:
    """The files under `folder` on host A's (this machine's root mount namespace's) disk, relative."""
    return sorted(str(p.relative_to(folder)) for p in folder.rglob("*") if p.is_file())
