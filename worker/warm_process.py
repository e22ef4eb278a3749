"""Warm case process: one long-lived Genesis process that builds a scene per case, or resets a kept one (reuse).

Protocol: the parent writes one JSON line per case ({"spec": path, "out_dir": path, "reuse": bool}) on stdin; this process answers
one JSON line ({"exit_status": int}) on the file descriptor given as argv[1]. During each case, fds 1 and 2 point at
that case's stdout.txt / stderr.txt, so evidence is captured per case exactly as in isolated mode.
"""

import json
import os
import sys
import traceback
from pathlib import Path

from rubric import parse_case


def _redirect(stdout_path: str, stderr_path: str) -> None:
    sys.stdout.flush()
    sys.stderr.flush()
    for fd, path in ((1, stdout_path), (2, stderr_path)):
        target = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
        os.dup2(target, fd)
        os.close(target)


def main(reply_fd: int) -> int:
    from .engine import run_case_in_genesis
    from .errors import EXIT_ERROR

    reply = os.fdopen(reply_fd, "w", buffering=1)
    for line in sys.stdin:
        request = json.loads(line)
        out_dir = Path(request["out_dir"])
        _redirect(str(out_dir / "stdout.txt"), str(out_dir / "stderr.txt"))
        try:
            spec = parse_case(json.loads(Path(request["spec"]).read_text()))
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
    sys.exit(main(int(sys.argv[1])))
