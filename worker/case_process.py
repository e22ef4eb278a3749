"""Parent side of case execution: start a case process, keep its output, validate what it wrote, return a result.

Never imports Genesis: the case runs in an isolated case process (`worker.isolated_process`, one process per case,
the lesson's contract) or in a warm case process (`worker.warm_process`, long-lived, a scene built per case or one
built for an earlier case of the same structure reset and reused, recycled after a bounded number of cases or any
error). Either way the parent accepts arrays only after checking shapes,
finiteness and provenance against the spec, and stops a case process whose resident memory passes the memory limit
(`MemoryWatch`), which fails the case with its own reason.
"""

from __future__ import annotations

import json
import os
import select
import signal
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Iterable
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

from rubric import CaseResult, Provenance, validate_arrays
from rubric.lesson import case_metrics
from rubric.results import discretization_problems
from rubric.specs import Timing

from .errors import EXIT_PROVENANCE, EXIT_RENDER, memory_limit_error

# A case spec of any installed lesson's kind (rubric.lesson.Lesson.case_kinds): rubric.specs' Timing and Execution
# fields, its kind and its name.
CaseKindSpec = Timing

DEFAULT_TIMEOUT_S = 900.0
# settings.case_memory_limit_mb's default (the worker's slot passes the setting); a case process imports no settings.
DEFAULT_MEMORY_LIMIT_MB = 3072
WARM_MAX_CASES = 500
EVIDENCE_FILES = ("arrays.npz", "arrays.tmp.npz", "provenance.json", "metrics.json", "stdout.txt", "stderr.txt")


def _case_process_env() -> dict[str, str]:
    env = dict(os.environ)
    # Headless rendering needs EGL; set before Genesis is imported in the case process so a warm one can render too.
    env.setdefault("PYOPENGL_PLATFORM", "egl")
    return env


class MemoryWatch:
    """Stops a case process whose resident memory (VmRSS, polled from /proc) passes `limit_mb`; `exceeded_mb` then
    says what it held. Resident memory rather than an RLIMIT_AS: torch reserves far more address space than a case
    uses (a CPU case: VmPeak several times its VmHWM; CUDA reserves tens of GB), so an address-space limit would refuse
    reservations, not memory. A limit of 0, or a host without /proc, watches nothing."""

    def __init__(self, pid: int, limit_mb: int, *, interval_s: float = 0.05):
        self.pid, self.limit_mb, self.interval_s = pid, limit_mb, interval_s
        self.exceeded_mb: int | None = None
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._watch, name=f"memory-watch-{pid}", daemon=True)

    def __enter__(self) -> "MemoryWatch":
        if self.limit_mb > 0 and _resident_mb(self.pid) is not None:
            self._thread.start()
        return self

    def __exit__(self, *exc) -> None:
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join()

    def _watch(self) -> None:
        while not self._stop.is_set():
            resident = _resident_mb(self.pid)
            if resident is None:  # ended
                return
            if resident > self.limit_mb:
                self.exceeded_mb = resident
                try:
                    os.kill(self.pid, signal.SIGKILL)
                except ProcessLookupError:
                    pass
                return
            self._stop.wait(self.interval_s)


def _resident_mb(pid: int) -> int | None:
    """A live process's resident memory in MB; None once it has ended (or where /proc is not)."""
    try:
        with open(f"/proc/{pid}/status") as status:
            for line in status:
                if line.startswith("VmRSS:"):
                    return int(line.split()[1]) // 1024
    except (FileNotFoundError, ProcessLookupError):
        return None
    return None  # a zombie has no VmRSS


def _prepare(spec: CaseKindSpec, out_dir: Path) -> Path:
    out_dir.mkdir(parents=True, exist_ok=True)
    # Stale evidence from an earlier run in this folder must never pass for this run's result.
    for name in EVIDENCE_FILES:
        (out_dir / name).unlink(missing_ok=True)
    spec_path = out_dir / "spec.json"
    spec_path.write_text(json.dumps(spec.model_dump(mode="json", exclude_computed_fields=True), indent=2))
    return spec_path


def run_case(
    spec: CaseKindSpec,
    out_dir: str | Path,
    *,
    mode: str = "isolated",
    timeout_s: float = DEFAULT_TIMEOUT_S,
    warm_process: "WarmCaseProcess | None" = None,
    memory_limit_mb: int = DEFAULT_MEMORY_LIMIT_MB,
) -> CaseResult:
    """Run one case and return its validated result; failures come back as results too, never as exceptions.
    `memory_limit_mb`: resident memory the case process may hold (0: no limit)."""
    out_dir = Path(out_dir)
    if mode == "warm":
        if warm_process is None:
            with WarmCaseProcess() as own:
                return own.run(spec, out_dir, timeout_s=timeout_s, memory_limit_mb=memory_limit_mb)
        return warm_process.run(spec, out_dir, timeout_s=timeout_s, memory_limit_mb=memory_limit_mb)
    if mode != "isolated":
        raise ValueError(f"mode must be 'isolated' or 'warm', got {mode!r}")
    spec_path = _prepare(spec, out_dir)
    started = time.perf_counter()
    command = [sys.executable, "-m", "worker.isolated_process", str(spec_path), str(out_dir)]
    process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                               errors="replace", env=_case_process_env())
    with MemoryWatch(process.pid, memory_limit_mb) as watch:
        try:
            stdout, stderr = process.communicate(timeout=timeout_s)
            status = process.returncode
        except subprocess.TimeoutExpired:
            process.kill()
            stdout, stderr = process.communicate()
            status = None
    (out_dir / "stdout.txt").write_text(stdout)
    (out_dir / "stderr.txt").write_text(stderr)
    return load_result(spec, out_dir, exit_status=status, mode=mode, wall_s=time.perf_counter() - started,
                       timeout_s=timeout_s, memory=(memory_limit_mb, watch.exceeded_mb))


def load_result(
    spec: CaseKindSpec,
    out_dir: Path,
    *,
    exit_status: int | None,
    mode: str,
    wall_s: float = 0.0,
    timeout_s: float = DEFAULT_TIMEOUT_S,
    memory: tuple[int, int | None] = (0, None),
) -> CaseResult:
    """Read and check what a case process left in out_dir. exit_status None means it was killed on timeout;
    `memory` is (the limit, MB held when the process was stopped for passing it, else None)."""
    stdout = _read(out_dir / "stdout.txt")
    stderr = _read(out_dir / "stderr.txt")
    base = dict(spec=spec, stdout=stdout, stderr=stderr, out_dir=str(out_dir), wall_s=wall_s)
    limit_mb, exceeded_mb = memory
    if exceeded_mb is not None:
        return CaseResult(status="failed", error=memory_limit_error(limit_mb, exceeded_mb), **base)
    if exit_status is None:
        return CaseResult(status="timeout", error=f"case process exceeded the {timeout_s:.0f} s time limit", **base)
    if exit_status != 0:
        return CaseResult(status="failed", error=_failure_reason(exit_status, stderr, stdout), **base)

    arrays_path, provenance_path = out_dir / "arrays.npz", out_dir / "provenance.json"
    if not arrays_path.exists() or not provenance_path.exists():
        return CaseResult(status="failed", error="case process exited 0 but wrote no arrays/provenance", **base)
    with np.load(arrays_path, allow_pickle=False) as npz:
        arrays = {name: npz[name] for name in npz.files}
    provenance = Provenance.model_validate_json(provenance_path.read_text())
    problems = _provenance_problems(spec, provenance, mode) + validate_arrays(spec, arrays, render=spec.render)
    problems += discretization_problems(spec, provenance.discretization, arrays.get("t"))
    if problems:
        return CaseResult(status="invalid", arrays=arrays, provenance=provenance, error="; ".join(problems), **base)
    metrics = case_metrics(spec, arrays)
    (out_dir / "metrics.json").write_text(metrics.model_dump_json(indent=2))
    return CaseResult(status="ok", arrays=arrays, provenance=provenance, metrics=metrics, **base)


def _provenance_problems(spec, provenance: Provenance, mode: str) -> list[str]:
    problems = []
    checks = {
        "case": spec.name,
        "requested_backend": spec.backend,
        "actual_backend": spec.backend,
        "precision": spec.precision,
        "seed": spec.seed,
        "execution_mode": mode,
    }
    for field, expected in checks.items():
        if getattr(provenance, field) != expected:
            problems.append(f"provenance.{field}: {getattr(provenance, field)!r}, expected {expected!r}")
    if spec.backend == "rocm" and not provenance.torch_hip:
        problems.append("provenance.torch_hip: a ROCm result must come from a HIP build of torch")
    rendering = provenance.rendering
    if rendering.requested != spec.render or rendering.status != ("OK" if spec.render else "SKIP"):
        problems.append(f"provenance.rendering: {rendering.status} (requested={rendering.requested}), spec render={spec.render}")
    return problems


def _failure_reason(exit_status: int, stderr: str, stdout: str = "") -> str:
    """The marked error line, else stderr's last line, else stdout's: a case process that died importing Genesis
    on a GPU host left its traceback on stdout only, and the reason must quote it rather than say nothing."""
    lines = [line for line in stderr.strip().splitlines() if line.strip()]
    marked = [line for line in lines if line.startswith(("PROVENANCE ERROR", "RENDER ERROR"))]
    out = [line for line in stdout.strip().splitlines() if line.strip()]
    tail = marked[-1] if marked else (lines[-1] if lines else (
        f"no output on stderr; stdout ends: {out[-1].strip()}" if out else "no output on stderr or stdout"))
    kind = {EXIT_PROVENANCE: "provenance error", EXIT_RENDER: "render error"}.get(exit_status, "case process failed")
    return f"{kind} (exit {exit_status}): {tail}"


def _read(path: Path) -> str:
    return path.read_text(errors="replace") if path.exists() else ""


class WarmCaseProcess:
    """One long-lived Genesis process building a scene per case (or reusing one of the same structure); recycled after
    max_cases or any failure."""

    def __init__(self, *, max_cases: int = WARM_MAX_CASES, reuse_scenes: bool = False,
                 warm_up_backend: str | None = None):
        self.max_cases = max_cases
        # Reset and reuse a scene built for an earlier case of the same structure (worker.engine.structure_key).
        self.reuse_scenes = reuse_scenes
        # A process started ahead of its first case (`start`) builds the lesson's scene structures on this backend
        # first (worker.warm_process); one started because a case is waiting does not.
        self.warm_up_backend = warm_up_backend
        self.cases_run = 0
        self.processes_started = 0
        self._proc: subprocess.Popen | None = None
        self._reply = None
        self._log = None
        # A process started to warm up answers one line when its warm-up is done, before any case's; this thread
        # reads it (`wait_warm`), so a case sent meanwhile waits for it and never reads it as its own answer.
        self._warming: threading.Thread | None = None
        self.warm_up: dict | None = None  # that line: {"warm_up_s": seconds, "ok": bool}, once read

    def __enter__(self) -> "WarmCaseProcess":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def start(self, on_warm: Callable[[dict], None] | None = None) -> None:
        """Start the process now rather than on the first case; it warms up, if asked, while nothing waits on it.
        A process started on a case (the first, or after a recycle or a failure) does not: a case is waiting.

        `on_warm(line)` is called (on a thread of its own) once the warm-up is done, failed or not (`ok` says), or
        at once when there is nothing to warm up."""
        if self._proc is None or self._proc.poll() is not None:
            self.close()
            self._start(warm_up=True)
            if self.warm_up_backend is not None:
                self._warming = threading.Thread(target=self._read_warm_up, args=(self._reply, on_warm), daemon=True,
                                                 name=f"warm-up-{self._proc.pid}")
                self._warming.start()
                return
        if on_warm is not None and self._warming is None:
            on_warm({"warm_up_s": 0.0, "ok": True})

    def _read_warm_up(self, reply, on_warm) -> None:
        line = reply.readline()  # "" when the process died warming up: the next case starts a new one
        try:
            self.warm_up = json.loads(line) if line else {"warm_up_s": None, "ok": False}
        except ValueError:
            self.warm_up = {"warm_up_s": None, "ok": False}
        if on_warm is not None:
            on_warm(self.warm_up)

    def wait_warm(self, timeout_s: float | None = None) -> bool:
        """Wait until the warm-up line was read (True), or `timeout_s` passed (False); True when none is pending."""
        if self._warming is not None:
            self._warming.join(timeout_s)
            if self._warming.is_alive():
                return False
            self._warming = None
        return True

    def _start(self, *, warm_up: bool = False) -> None:
        read_fd, write_fd = os.pipe()
        self._log = tempfile.TemporaryFile()
        warm_up = [self.warm_up_backend, str(int(self.reuse_scenes))] if warm_up and self.warm_up_backend else []
        self._proc = subprocess.Popen(
            [sys.executable, "-m", "worker.warm_process", str(write_fd), *warm_up],
            stdin=subprocess.PIPE,
            stdout=self._log,
            # The worker's own log: what the process says before its first case (its warm-up, a crash at start).
            # Each case's output goes to that case's stdout.txt / stderr.txt (worker.warm_process).
            stderr=None,
            pass_fds=(write_fd,),
            env=_case_process_env(),
            text=True,
        )
        os.close(write_fd)
        self._reply = os.fdopen(read_fd, "r")
        self.cases_run = 0
        self.processes_started += 1

    def close(self) -> None:
        if self._proc is None:
            return
        try:
            self._proc.stdin.close()
            self._proc.wait(timeout=30)
        except (subprocess.TimeoutExpired, OSError):
            self._proc.kill()
            self._proc.wait()
        if self._warming is not None:
            self._warming.join(5)  # the process is gone: its reader sees the end of the pipe
        self._warming = None
        self._reply.close()
        self._log.close()
        self._proc = self._reply = self._log = None

    @property
    def pid(self) -> int | None:
        return self._proc.pid if self._proc else None

    def run(self, spec, out_dir: str | Path, *, timeout_s: float = DEFAULT_TIMEOUT_S,
            memory_limit_mb: int = DEFAULT_MEMORY_LIMIT_MB) -> CaseResult:
        """Run one case; the process (whatever earlier cases left in it) is held to the memory limit meanwhile."""
        out_dir = Path(out_dir)
        started = time.perf_counter()
        if not self.wait_warm(timeout_s):  # a case sent while the process warms up waits for it, within its limit
            self._proc.kill()
            self.close()
            _prepare(spec, out_dir)
            return load_result(spec, out_dir, exit_status=None, mode="warm",
                               wall_s=time.perf_counter() - started, timeout_s=timeout_s)
        if self._proc is None or self._proc.poll() is not None or self.cases_run >= self.max_cases:
            self.close()
            self._start()
        spec_path = _prepare(spec, out_dir)
        started = time.perf_counter()
        with MemoryWatch(self._proc.pid, memory_limit_mb) as watch:
            request = {"spec": str(spec_path), "out_dir": str(out_dir), "reuse": self.reuse_scenes}
            try:
                self._proc.stdin.write(json.dumps(request) + "\n")
                self._proc.stdin.flush()
            except BrokenPipeError:  # stopped already (by the watch, over its limit since its last case)
                pass
            self.cases_run += 1
            ready, _, _ = select.select([self._reply], [], [], timeout_s)
            line = self._reply.readline() if ready else ""
        if not line:
            # Timed out or died mid-case: the process is not trusted with another case.
            self._proc.kill()
            self.close()
            exit_status = None if not ready else -9
        else:
            exit_status = json.loads(line)["exit_status"]
            if exit_status != 0:
                self.close()
        return load_result(spec, out_dir, exit_status=exit_status, mode="warm",
                           wall_s=time.perf_counter() - started, timeout_s=timeout_s,
                           memory=(memory_limit_mb, watch.exceeded_mb))


def run_cases(
    specs: Iterable[CaseKindSpec],
    out_root: str | Path,
    *,
    mode: str = "isolated",
    jobs: int = 1,
    timeout_s: float = DEFAULT_TIMEOUT_S,
    progress: Callable[[CaseResult], None] | None = None,
) -> dict[str, CaseResult]:
    """Run several cases, each into out_root/NAME; results by case name, in the order given."""
    specs = list(specs)
    out_root = Path(out_root)
    results: dict[str, CaseResult] = {}

    def done(result: CaseResult) -> CaseResult:
        if progress:
            progress(result)
        return result

    if mode == "warm":
        with WarmCaseProcess() as warm_process:
            for spec in specs:
                results[spec.name] = done(warm_process.run(spec, out_root / spec.name, timeout_s=timeout_s))
        return results
    with ThreadPoolExecutor(max_workers=max(1, jobs)) as pool:
        futures = [(spec, pool.submit(run_case, spec, out_root / spec.name, timeout_s=timeout_s)) for spec in specs]
        for spec, future in futures:
            results[spec.name] = done(future.result())
    return results
