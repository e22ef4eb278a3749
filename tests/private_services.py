"""Servers a test owns alone: a Redis and a PostgreSQL cluster on free loopback ports, restartable at will.

The shared services (tests/services.py) serve every test at once; a test that restarts its broker or database needs
its own. Redis saves nothing to disk, so its restart loses every message; PostgreSQL keeps its data, and its restart
cuts every connection. A missing server binary is `services.unavailable` (a skip, a failure with CI=true).
"""

from __future__ import annotations

import os
import shutil
import subprocess
import tempfile
import time
from pathlib import Path

from tests import services


def _wait_for(predicate, what: str, log: Path, limit_s: float = services.STARTUP_LIMIT_S) -> None:
    deadline = time.monotonic() + limit_s
    while not predicate():
        if time.monotonic() > deadline:
            raise RuntimeError(f"{what} did not come up:\n{log.read_text(errors='replace')[-3000:]}")
        time.sleep(0.1)


class PrivateRedis:
    """redis-server on a free port, no persistence: a restart loses every message, as the issue's fault does."""

    def __init__(self, folder: Path, address: str = "127.0.0.1"):
        self.binary = shutil.which("redis-server")
        self.address = address  # another test host reaches it on a veth address (tests/integration/hosts.py)
        if self.binary is None:
            services.unavailable("redis-server", FileNotFoundError("redis-server is not on PATH"))
        self.port = services.free_port()
        self.folder = folder
        self.log = folder / "redis.log"
        self.proc: subprocess.Popen | None = None

    @property
    def url(self) -> str:
        return f"redis://{self.address}:{self.port}/0"

    def _ping(self) -> bool:
        import redis

        try:
            return bool(redis.Redis(host=self.address, port=self.port, socket_timeout=0.5).ping())
        except redis.RedisError:
            return False

    def start(self) -> None:
        self.proc = subprocess.Popen(
            [self.binary, "--port", str(self.port), "--bind", self.address, "--save", "", "--appendonly", "no",
             "--protected-mode", "no", "--dir", str(self.folder)],  # no password, on a private test address
            stdout=self.log.open("ab"), stderr=subprocess.STDOUT, start_new_session=True)
        _wait_for(self._ping, "private redis", self.log)

    def stop(self) -> None:
        """SIGKILL: nothing saved, every queue gone."""
        if self.proc is not None and self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait()

    def restart(self) -> None:
        """Kill and start again on the same port, empty; returns once it answers."""
        self.stop()
        self.start()


class PrivatePostgres:
    """A throwaway cluster (initdb, trust auth, fsync off) on a free port.

    PostgreSQL refuses to run as root: as root it runs as user postgres (`runuser`), in its own temporary directory
    owned by postgres (pytest's tmp_path is private to root); as anyone else, as that user."""

    def __init__(self, address: str = "127.0.0.1"):
        self.address = address  # another test host reaches it on a veth address (tests/integration/hosts.py)
        self.bin = Path(shutil.which("pg_ctl") or "/usr/lib/postgresql/15/bin/pg_ctl").resolve().parent
        self.as_postgres = ["runuser", "-u", "postgres", "--"] if os.geteuid() == 0 else []
        if not (self.bin / "initdb").exists() or (self.as_postgres and shutil.which("runuser") is None):
            services.unavailable("PostgreSQL initdb/pg_ctl", FileNotFoundError(f"no initdb or runuser ({self.bin})"))
        self.port = services.free_port()
        self.folder = Path(tempfile.mkdtemp(prefix="grader-test-postgres-"))
        self.data = self.folder / "pgdata"
        self.log = self.folder / "postgres.log"
        if self.as_postgres:
            shutil.chown(self.folder, "postgres")

    @property
    def url(self) -> str:
        return f"postgresql+psycopg2://postgres@{self.address}:{self.port}/postgres"

    def _as_postgres(self, *argv: str) -> None:
        done = subprocess.run([*self.as_postgres, *argv], capture_output=True, text=True)
        if done.returncode != 0:
            raise RuntimeError(f"{argv[0]} failed: {done.stdout[-2000:]}{done.stderr[-2000:]}")

    def _ctl(self, action: str, *extra: str) -> None:
        options = (f"-p {self.port} -k {self.folder} -c listen_addresses={self.address} -c fsync=off "
                   "-c max_connections=50")
        self._as_postgres(str(self.bin / "pg_ctl"), action, "-D", str(self.data), "-l", str(self.log), "-w",
                          "-t", str(services.STARTUP_LIMIT_S), "-o", options, *extra)

    def start(self) -> None:
        if not self.data.exists():
            self._as_postgres(str(self.bin / "initdb"), "-D", str(self.data), "-U", "postgres", "-A", "trust",
                              "--no-sync", "-E", "UTF8")
            with (self.data / "pg_hba.conf").open("a") as hba:  # initdb trusts loopback only
                hba.write("host all all samenet trust\n")
        self._ctl("start")

    def stop(self) -> None:
        """Stop (immediate: it is thrown away) and remove the cluster."""
        if (self.data / "postmaster.pid").exists():
            self._ctl("stop", "-m", "immediate")
        shutil.rmtree(self.folder, ignore_errors=True)

    def restart(self) -> None:
        """Stop (fast: every connection terminated) and start again; returns once it accepts connections."""
        self._ctl("restart", "-m", "fast")
