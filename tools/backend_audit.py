"""The lesson's check cases on two backends of one host, compared through the audit log, for a GPU host that has
Genesis but not the service (no database, no broker): the case processes run there, the comparison runs here.

    # on the GPU host: N1-N4 and both friction cases on cpu and on cuda, isolated processes, side by side
    python -m tools.backend_audit run --out runs --backends cpu,cuda
    # here: the cpu runs become a submission's case runs, the cuda runs audit re-runs of them, and
    # worker.audit writes the entries (classification, differences, relations) as a worker would
    python -m tools.backend_audit compare runs --left cpu --right cuda

`run` needs only rubric/ and worker/ (the case processes); `compare` uses a throw-away SQLite database under
--data-dir unless DATABASE_URL says otherwise. Every case result is kept as the case process wrote it.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path


def run(out: Path, backends: list[str], mode: str) -> int:
    from rubric import CHECK_CASES, get_case, with_backend
    from rubric.check import OutputLocation, evaluate
    from worker import run_cases

    def one(backend: str) -> dict:
        specs = [with_backend(get_case(name), backend=backend, render=False) for name in CHECK_CASES]
        started = time.perf_counter()
        results = run_cases(specs, out / backend, mode=mode, progress=lambda r: print(
            f"  {backend:5s} {r.spec.name:20s} {r.status:8s} {r.wall_s:6.1f} s "
            f"{(r.provenance.actual_backend + ' ' + (r.provenance.device_name or '')) if r.provenance else r.error}",
            flush=True))
        for name, result in results.items():  # what `compare` needs to read the folder back (worker.load_result)
            (out / backend / name / "outcome.json").write_text(json.dumps(
                {"status": result.status, "error": result.error, "wall_s": result.wall_s, "mode": mode}))
        return {"backend": backend, "wall_s": round(time.perf_counter() - started, 1), "results": results}

    with ThreadPoolExecutor(len(backends)) as pool:  # one process per case; the backends side by side
        done = list(pool.map(one, backends))
    failed = 0
    for item in done:
        npz = len(list((out / item["backend"]).rglob("*.npz")))  # as `grader check` judges a folder outside git
        where = OutputLocation(passed=npz > 0, evidence=f"{npz} .npz files under {out / item['backend']}")
        report = evaluate(item["results"], outputs=where)
        (out / item["backend"] / "check.txt").write_text(report.render_text() + "\n")
        print(f"\n== {item['backend']}: {len(item['results'])} cases in {item['wall_s']} s ==")
        print(report.render_text())
        failed += sum(not r.ok for r in item["results"].values())
    return 1 if failed else 0


def compare(runs: Path, left: str, right: str, data_dir: Path) -> int:
    os.environ.setdefault("DATA_DIR", str(data_dir))
    os.environ.setdefault("DATABASE_URL", f"sqlite:///{data_dir / 'audit.db'}")
    os.environ.setdefault("ARTIFACTS_DIR", str(data_dir / "artifacts"))
    # lazy: settings read the environment set just above
    from grader.core import content_key, lifecycle
    from grader.core.audit import create_audit_rerun
    from grader.core.db import migrate, new_session
    from grader.core.models import Submission
    from grader.services.identity import accounts
    from worker import load_result
    from worker.audit import audit_finished_run

    migrate()
    with new_session() as session:
        course = accounts.get_or_create_course(session=session, name="backend-audit")
        student = accounts.get_or_create_user(session=session, course=course, name="check", role="student")
        auditor = accounts.get_or_create_user(session=session, course=course, name="auditor", role="auditor")
        names = sorted(p.name for p in (runs / left).iterdir() if (p / "outcome.json").exists())
        lefts = {name: _load(load_result, runs / left / name) for name in names}
        rights = {name: _load(load_result, runs / right / name) for name in names
                  if (runs / right / name / "outcome.json").exists()}
        submission = Submission(course_id=course.id, student_id=student.id, lesson="L03", sheet={}, force_rerun=True)
        session.add(submission)
        session.flush()
        entries = []
        for name, result in lefts.items():
            source = _stored(session, lifecycle, content_key, submission, result)
            if name not in rights:
                continue
            spec = rights[name].spec
            rerun = create_audit_rerun(session, source=source, backend=spec.backend, precision=spec.precision,
                                       mode="isolated", user=auditor)
            session.commit()
            _finish(session, lifecycle, content_key, rerun, rights[name])
            entries += audit_finished_run(session, rerun.id)
        print(f"audit log: {len(entries)} entries ({left} against {right}), database {os.environ['DATABASE_URL']}")
        for e in entries:
            print(f"\n[{e.classification}] {e.case}: {e.left_variant} vs {e.right_variant}")
            print(f"  {e.summary}")
            comparison = e.comparison or {}
            for a in comparison.get("arrays", []):
                print(f"  array  {a['name']:22s} max |diff| {_g(a['max_abs'])} rms {_g(a['rms'])} {a['unit']:13s}"
                      f"{'bit-equal ' if a['bit_equal'] else ''}{'within' if a['within'] else 'OUTSIDE'} "
                      f"{a['tolerance']} ({a['tolerance_value']:g})")
            for m in comparison.get("metrics", []):
                if m["left"] != m["right"]:
                    print(f"  metric {m['name']:26s} {m['left']!s:>22.22} vs {m['right']!s:<22.22} "
                          f"{'within' if m['within'] else 'OUTSIDE'} {m['tolerance'] or ''}")
            for r in comparison.get("relations", []):
                print(f"  relation {r['id']}: {r['left']} vs {r['right']}{' CHANGED' if r['changed'] else ''}")
    return 0


def _g(value) -> str:
    return f"{value:>10.3g}" if isinstance(value, float) else f"{value!s:>10}"


def _load(load_result, folder: Path):
    from rubric import parse_case  # lazy: as the other imports of `compare`

    outcome = json.loads((folder / "outcome.json").read_text())
    spec = parse_case(json.loads((folder / "spec.json").read_text()))
    return load_result(spec, folder, exit_status=0 if outcome["status"] == "ok" else 1, mode=outcome["mode"],
                       wall_s=outcome["wall_s"])


def _stored(session, lifecycle, content_key, submission, result):
    from grader.core.models import CaseRun  # lazy: this tool's DB imports only after the environment is set

    spec = result.spec.model_dump(mode="json", exclude_computed_fields=True)
    from grader.core.audit import spec_key  # lazy: as above

    run = CaseRun(submission_id=submission.id, name=result.spec.name, kind=result.spec.kind,
                  backend=result.spec.backend, precision=result.spec.precision, spec=spec, spec_key=spec_key(spec))
    session.add(run)
    session.commit()
    _finish(session, lifecycle, content_key, run, result)
    return run


def _finish(session, lifecycle, content_key, run, result) -> None:
    """The worker's own steps for a finished case: claim the delivery, then store the result (grader.core.lifecycle)."""
    claimed, _ = lifecycle.claim(session=session, case_run_id=run.id, delivery=run.delivery)
    assert claimed is not None, f"case run {run.id} could not be claimed"
    inputs = content_key.key_inputs(run.spec, backend=run.backend, precision=run.precision)
    run.content_key = content_key.content_key(inputs)
    lifecycle.store_result(session=session, run=run, result=result, key_inputs=inputs)
    session.commit()


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m tools.backend_audit", description=__doc__.split("\n\n")[0])
    sub = parser.add_subparsers(dest="command", required=True)
    p_run = sub.add_parser("run", help="run the check cases on each backend (case processes only)")
    p_run.add_argument("--out", type=Path, required=True)
    p_run.add_argument("--backends", default="cpu,cuda")
    p_run.add_argument("--mode", default="isolated", choices=("isolated", "warm"))
    p_cmp = sub.add_parser("compare", help="store both sides and let worker.audit compare them")
    p_cmp.add_argument("runs", type=Path)
    p_cmp.add_argument("--left", default="cpu")
    p_cmp.add_argument("--right", default="cuda")
    p_cmp.add_argument("--data-dir", type=Path, default=None)
    args = parser.parse_args(argv)
    if args.command == "run":
        return run(args.out, args.backends.split(","), args.mode)
    data_dir = args.data_dir or Path(tempfile.mkdtemp(prefix="backend-audit-"))
    data_dir.mkdir(parents=True, exist_ok=True)
    return compare(args.runs, args.left, args.right, data_dir)


if __name__ == "__main__":
    sys.exit(main())
