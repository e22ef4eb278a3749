"""Warm case process: one long-lived Genesis process that builds a scene per case, or resets a kept one (reuse).

Started with a backend to warm up, it first builds the lessons' scene structures (`warm_up`), then serves.

Protocol: the parent writes one JSON line per case ({"spec": path, "out_dir": path, "reuse": bool}) on stdin; this process answers
one JSON line ({"exit_status": int}) on the file descriptor given as argv[1], after one line ({"warm_up_s": float, "ok":
bool}) when it was started to warm up. During each case, fds 1 and 2 point at
that case's stdout.txt / stderr.txt, so evidence is captured per case exactly as in isolated mode.
"""

import json
import os
import signal
import sys
import tempfile
import time
import traceback
from pathlib import Path

from rubric.lesson import lesson, lesson_names, parse_spec

from .errors import EXIT_ERROR
from .kernel_cache import compile_once


def _redirect(stdout_path: str, stderr_path: str) -> None:
    sys.stdout.flush()
    sys.stderr.flush()
    for fd, path in ((1, stdout_path), (2, stderr_path)):
        target = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
        os.dup2(target, fd)
        os.close(target)


def _exit_on_sigterm(signum, _frame) -> None:
    """SIGTERM (a stopped worker's process group, `docker stop` of a bare container) ends this process through
    Python's exit path: Genesis' atexit `destroy` then writes the kernels compiled since start to the offline kernel
    cache. Killed by the signal's default action instead, every later worker on the machine compiled them again
    (~75 s on its first case: seen by the benchmark, whose stacks end with SIGTERM to the group)."""
    raise SystemExit(128 + signum)


def warm_up_cases() -> list[tuple[str, object]]:
    """(name, spec) of every installed lesson's warm-up cases (Lesson.warm_up_cases: one per scene structure its cases
    use), so that a submission's first cases build no scene, as a later submission's do not (an L03 first submission
    once warm took 2.3x a cold one when only two of its structures were built, issue 35)."""
    return [(name, declared.cases[name]) for declared in map(lesson, lesson_names()) for name in declared.warm_up_cases]


WARM_UP_DONE = "warm case process warmed up"  # the line it writes to the worker's log when done


def warm_up(backend: str, reuse: bool, *, said: str = WARM_UP_DONE) -> dict:
    """Build and run the lessons' scene structures (`warm_up_cases`) on `backend` into a folder removed after, before any
    case: Genesis imported and initialised, kernels loaded, and (with reuse) every scene kept for the first cases. What
    it did, or why it failed, goes to its stderr, the worker's own log (one WARM_UP_DONE line); a real case never
    depends on it. Returns the line the parent reads: {"warm_up_s": seconds, "ok": every structure ran}."""
    # lazy: worker.engine only inside the case process; parents import this module for WARM_UP_DONE
    from .engine import run_case_in_genesis

    started = time.perf_counter()
    statuses = {}
    with tempfile.TemporaryDirectory(prefix="warm-up-") as folder:
        for name, case in warm_up_cases():
            spec = case.model_copy(update={"backend": backend})
            out_dir = Path(folder) / name
            out_dir.mkdir()
            try:
                statuses[name] = run_case_in_genesis(spec, out_dir, mode="warm", reuse=reuse)
            except Exception:  # noqa: BLE001 - logged; the first real case meets the same fault and records it
                traceback.print_exc()
                statuses[name] = "raised"
    outcome = ", ".join(f"{name} exit {status}" for name, status in statuses.items())
    seconds = time.perf_counter() - started
    print(f"{said} on {backend} in {seconds:.1f} s ({outcome}; pid {os.getpid()})", file=sys.stderr,
          flush=True)
    return {"warm_up_s": round(seconds, 3), "ok": all(status == 0 for status in statuses.values())}


def main(reply_fd: int, warm_up_backend: str | None = None, reuse: bool = False) -> int:
    signal.signal(signal.SIGTERM, _exit_on_sigterm)
    if warm_up_backend:
        # Before Genesis is imported here: on a fresh machine one slot compiles the kernels, the others wait and load.
        compile_once(warm_up_backend)
    # lazy: worker.engine only inside the case process; parents import this module for WARM_UP_DONE
    from .engine import run_case_in_genesis

    reply = os.fdopen(reply_fd, "w", buffering=1)
    if warm_up_backend:
        # One line before any case's: the parent (worker.case_process.WarmCaseProcess.start) is told it is warm.
        reply.write(json.dumps(warm_up(warm_up_backend, reuse)) + "\n")
    for line in sys.stdin:
        request = json.loads(line)
        out_dir = Path(request["out_dir"])
        _redirect(str(out_dir / "stdout.txt"), str(out_dir / "stderr.txt"))
        try:
            spec = parse_spec(json.loads(Path(request["spec"]).read_text()))
            status = run_case_in_genesis(spec, out_dir, mode="warm", reuse=bool(request.get("reuse")))
        except Exception:
            traceback.print_exc()
            status = EXIT_ERROR
        sys.stdout.flush()
        sys.stderr.flush()
        _redirect(os.devnull, os.devnull)
        reply.write(json.dumps({"exit_status": status}) + "\n")
    return 0


if __name__ == "__main__":
    # argv: REPLY_FD [WARM_UP_BACKEND REUSE(0|1)]
    sys.exit(main(int(sys.argv[1]), *(sys.argv[2:3]), *(bool(int(a)) for a in sys.argv[3:4])))
