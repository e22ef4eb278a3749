"""Issue 34 item 6: per-student variants on one CPU worker (Redis + PostgreSQL).

- **A pool of K**, generated through the API (`POST /v1/assignments/ID/variants`) and timed until it is ready (every
  drawn variant measured and checked, or dropped); the time per drawn variant is set against one cold reference
  submission (force_rerun: every case run measured) on the same stack, measured just before.
- **A class on variants against the same class without**: each student submits the sheet right for their own lab to
  an assignment on the pool, and the reference sheet to an assignment without one. Every case run of both classes
  is a stored measurement (the shipped lesson's, measured by the cold submissions; the pool's), so what variants add
  is what the service does per sheet on top: the student's variant read at submission, and the copy evidence (the
  sheet graded again on every other kept variant's stored runs).

Students' variants are fixed before the class is timed (as at their first view of the form); the assignment on the
pool is opened by moving its open_at back in the database, as the variant test does, since a pool is measured
before its assignment opens.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from datetime import UTC, datetime, timedelta

from sqlalchemy import func, select
from sqlalchemy.orm import Session

from grader.core.models import CaseRun, CopyFlag, Grade, PoolVariant, Submission, VariantPool
from tools.bench.cases import BenchFailure
from tools.bench.classroom import wait_until_warm
from tools.bench.stats import median
from tools.bench.submission import WAIT_LIMIT_S, reference_sheet, time_submission
from tools.harness.sheets import open_with_variants, sheet_right_for
from tools.harness.stack import COURSE

SEED = 391  # its first three variants: two kept, one dropped by the lab check (tests/integration/test_variants.py)



def _iso(delta: timedelta) -> str:
    return (datetime.now(UTC).replace(microsecond=0) + delta).isoformat()


def _assignment(prof, title: str) -> int:
    return prof.create_assignment(COURSE, {"title": title, "part": "sheet", "open_at": _iso(timedelta(hours=1)),
                                           "due_at": _iso(timedelta(days=2)),
                                           "hard_close_at": _iso(timedelta(days=3))})["id"]


def _pool(stack, prof, assignment_id: int, k: int, log) -> dict:
    """Generate the pool and wait until ready: its seconds, the variants kept and dropped, the runs it measured."""
    started = time.monotonic()
    prof.generate_variants(assignment_id, {"seed": SEED, "k": k})
    deadline = started + WAIT_LIMIT_S * k
    while (pool := prof.variants(assignment_id))["state"] != "ready":
        if stack.worker.poll() is not None:
            raise BenchFailure(f"the worker exited ({stack.worker.returncode}) while the pool was measured")
        if time.monotonic() > deadline:
            raise BenchFailure(f"pool of {k}: not ready after {deadline - started:.0f} s: {pool}")
        states = [v["state"] for v in pool["variants"]]
        log(f"  pool: {states.count('kept')} kept, {states.count('dropped')} dropped, "
            f"{len(states) - states.count('kept') - states.count('dropped')} measuring "
            f"({time.monotonic() - started:.0f} s)")
        time.sleep(5)
    seconds = time.monotonic() - started
    with Session(stack.engine) as session:
        measuring = list(session.scalars(select(PoolVariant.submission_id).join(VariantPool).where(
            VariantPool.assignment_id == assignment_id, PoolVariant.submission_id.is_not(None))))
        runs = session.scalars(select(CaseRun).where(CaseRun.submission_id.in_(measuring))).all()
    dropped = [(v["id"], v["reason"]) for v in pool["variants"] if v["state"] == "dropped"]
    # issue 47: K is kept; the pool draws past its drops, so the cost that matters is per kept variant
    drawn = len(pool["variants"])
    return {"k": k, "seed": SEED, "pool_s": seconds, "drawn": drawn, "per_variant_s": seconds / max(1, drawn),
            "per_kept_s": seconds / max(1, pool["kept"]), "kept": pool["kept"],
            "dropped": len(dropped), "dropped_reasons": dropped, "case_runs": len(runs),
            "measured_runs": sum(1 for r in runs if r.reused_from_id is None)}


def _class(stack, assignment_id: int, sheets: dict[str, dict], log) -> dict:
    """Every student posts their sheet back to back; timed from the first POST to the last stored grade (and to the
    last report complete)."""
    started_at = datetime.now(UTC).replace(tzinfo=None)
    started = time.monotonic()
    for name, sheet in sheets.items():
        stack.client(name).submit(sheet, assignment_id=assignment_id)
    posted_s = time.monotonic() - started
    mine = select(Submission).where(Submission.assignment_id == assignment_id)
    deadline = started + WAIT_LIMIT_S * max(1, len(sheets) // 20)
    while True:
        with Session(stack.engine) as session:
            subs = session.scalars(mine).all()
            ids = [s.id for s in subs if s.student.name in sheets]
            done = [s for s in subs if s.id in ids and s.status in ("graded", "failed")]
            completing = session.scalar(select(func.count()).select_from(Grade).where(
                Grade.submission_id.in_(ids), Grade.completed_at.is_(None)))
            last = max((s.graded_at for s in done if s.graded_at), default=None)
            completed = session.scalar(select(func.max(Grade.completed_at)).where(Grade.submission_id.in_(ids)))
            reused = session.scalar(select(func.count()).select_from(CaseRun).where(
                CaseRun.submission_id.in_(ids), CaseRun.reused_from_id.is_(None)))
            flags = session.scalar(select(func.count()).select_from(CopyFlag).where(CopyFlag.submission_id.in_(ids)))
        if len(done) >= len(sheets) and not completing:
            break
        if stack.worker.poll() is not None:
            raise BenchFailure(f"the worker exited ({stack.worker.returncode}) with {len(done)} graded")
        if time.monotonic() > deadline:
            raise BenchFailure(f"class: {len(done)} of {len(sheets)} finished when the wait limit passed")
        time.sleep(1)
    failed = [s.id for s in done if s.status == "failed"]
    if failed:
        raise BenchFailure(f"class: submissions {failed} failed")
    return {"submissions": len(sheets), "posting_s": posted_s, "total_s": (last - started_at).total_seconds(),
            "complete_s": (completed - started_at).total_seconds() if completed else None,
            "runs_measured": reused, "copy_flags": flags}


def bench_variants(stack, k: int, size: int, repeats: int, log: Callable[[str], None] = print) -> dict:
    wait_until_warm(stack, log)
    prof = stack.client("prof")
    cold = []
    for r in range(repeats):  # the shipped lesson's runs measured, as the class without variants reuses them
        cold.append(time_submission(prof, reference_sheet(), worker=stack.worker, force_rerun=True).graded_s)
        log(f"  cold reference submission {r + 1}/{repeats}: {cold[-1]:.2f} s")
    on_pool = _assignment(prof, "Bench on variants")
    log(f"== a pool of {k} variants (seed {SEED})")
    pool = _pool(stack, prof, on_pool, k, log)
    log(f"  pool ready in {pool['pool_s']:.1f} s: {pool['kept']} kept, {pool['dropped']} dropped; "
        f"{pool['measured_runs']} of {pool['case_runs']} case runs measured")
    if not pool["kept"]:
        raise BenchFailure(f"pool of {k}: no variant kept ({pool['dropped_reasons']})")
    plain = _assignment(prof, "Bench without variants")
    students = stack.students[:size]
    open_with_variants(stack.engine, plain, [])
    given = {name: parameters for name, (_, parameters) in open_with_variants(stack.engine, on_pool, students).items()}
    log(f"== a class of {size} without variants")
    without = _class(stack, plain, {name: reference_sheet() for name in students}, log)
    log(f"  {without['total_s']:.1f} s, {without['runs_measured']} runs measured")
    log(f"== the same class on {pool['kept']} kept variants")
    on = _class(stack, on_pool, {name: sheet_right_for(given[name]) for name in students}, log)
    log(f"  {on['total_s']:.1f} s, {on['runs_measured']} runs measured, {on['copy_flags']} copy flags")
    return {"stack": stack.kind, "cold_s": median(cold), "cold_samples_s": cold, "pool": pool,
            "variants_used": len({tuple(sorted(p.items())) for p in given.values()}),
            "class_without": without, "class_on_variants": on,
            "per_variant_over_cold": pool["per_variant_s"] / median(cold),
            "per_kept_over_cold": pool["per_kept_s"] / median(cold),
            "class_ratio": on["total_s"] / without["total_s"]}


def format_variants(f: dict, verdict: Callable[..., str]) -> list[str]:
    pool, on, off = f["pool"], f["class_on_variants"], f["class_without"]
    return [f"per-student variants, {f['stack']}, one CPU worker:",
            f"  pool of {pool['k']} (seed {pool['seed']}): ready in {pool['pool_s']:.1f} s, {pool['kept']} kept, "
            f"{pool['dropped']} dropped; {pool['measured_runs']} of {pool['case_runs']} case runs measured",
            f"  per kept variant {pool['per_kept_s']:6.2f} s | cold reference submission {f['cold_s']:.2f} s "
            f"(median of {len(f['cold_samples_s'])}): {f['per_kept_over_cold']:.2f}x   "
            f"{verdict('variant_over_cold', f['per_kept_over_cold'])}",
            f"  per drawn variant {pool['per_variant_s']:6.2f} s ({pool['drawn']} drawn): "
            f"{f['per_variant_over_cold']:.2f}x",
            f"  class of {off['submissions']} without variants   {off['total_s']:7.1f} s "
            f"({off['runs_measured']} runs measured)",
            f"  the same class on {f['variants_used']} variants {on['total_s']:7.1f} s "
            f"({on['runs_measured']} runs measured, {on['copy_flags']} copy flags): {f['class_ratio']:.2f}x   "
            f"{verdict('variants_class_ratio', f['class_ratio'])}"]
