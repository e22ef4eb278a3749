"""Resident memory of a worker over many cases: the RSS of the Celery worker process and every process under it
(the prefork child and its warm case process), sampled after each submission measured afresh."""

from __future__ import annotations

from collections.abc import Callable

import psutil

from tools.bench.stats import growth_pct
from tools.bench.submission import reference_sheet, time_submission

MB = 1024 * 1024


def worker_rss(pid: int) -> dict[str, float]:
    """RSS in MB of pid and each of its descendants, by 'pid name'."""
    root = psutil.Process(pid)
    out = {}
    for proc in (root, *root.children(recursive=True)):
        try:
            out[f"{proc.pid} {proc.name()}"] = proc.memory_info().rss / MB
        except psutil.NoSuchProcess:
            continue
    return out


def bench_memory(stack, cases: int, log: Callable[[str], None] = print) -> dict:
    """Submit the reference sheet with force_rerun until at least `cases` case runs were measured on the warm case
    process; sample the worker's RSS after each. The first sample follows a warm-up submission, so growth is what
    the cases add, not the process start-up."""
    client = stack.client("prof")  # force_rerun is a staff power
    sheet = reference_sheet()
    time_submission(client, sheet, worker=stack.worker, force_rerun=True)
    samples = [{"cases": 0, "rss_mb": worker_rss(stack.worker.pid)}]
    done = 0
    while done < cases:
        state = time_submission(client, sheet, worker=stack.worker, force_rerun=True).state
        done += state["progress"]["total"]
        samples.append({"cases": done, "rss_mb": worker_rss(stack.worker.pid)})
        total = sum(samples[-1]["rss_mb"].values())
        if len(samples) % 5 == 0 or done >= cases:
            log(f"  {done} cases: worker total RSS {total:.0f} MB")
    totals = [sum(s["rss_mb"].values()) for s in samples]
    return {"stack": stack.kind, "cases": done, "first_mb": totals[0], "last_mb": totals[-1], "max_mb": max(totals),
            "growth_pct": growth_pct(totals[0], totals[-1]), "last_by_process_mb": samples[-1]["rss_mb"],
            "samples": [{"cases": s["cases"], "total_mb": t} for s, t in zip(samples, totals, strict=True)]}
