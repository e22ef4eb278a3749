"""Reads of graded reports that keep up: 50 concurrent readers against one API process and against the deployed
shape (API_WORKERS uvicorn processes over PostgreSQL and Redis), side by side in one run.

Each reader reads a graded submission's four answers in turn (the report page, results.json, /v1/submissions/ID and
its /grade), either plainly (every read answered in full: a first visit) or conditionally (the reader keeps each
answer's ETag and sends it back as If-None-Match, as a polling page or a refreshing browser does: a 304 when
nothing changed). The shapes take turns within each repeat, each started afresh, warmed up, measured and stopped, so
both see the same machine; figures are medians over the repeats, with the ratios of one shape to the other."""

from __future__ import annotations

import asyncio
import os
import random
import time
from collections import Counter
from collections.abc import Callable
from pathlib import Path

import httpx
from tools.harness.processes import free_port, start_api, stop
from tools.harness.stack import service_stack
from tools.bench.stats import latency_summary, median

READS = ("/submissions/{id}", "/submissions/{id}/results.json", "/v1/submissions/{id}", "/v1/submissions/{id}/grade")
MODES = ("plain", "conditional")
STACK = "redis-pg"  # the deployed shape's database and broker (docker-compose.yml)
# The deployed shape: the api service's API_WORKERS in docker-compose.yml, or this run's environment's.
DEPLOYED_WORKERS = int(os.environ.get("API_WORKERS", "2"))
SUMMARY = ("p50_ms", "p95_ms", "p99_ms", "requests_per_s")


async def _reader(http: httpx.AsyncClient, paths: list[str], requests: int, think_s: float, conditional: bool,
                  latencies: list, statuses: Counter, errors: list, not_modified: list | None = None) -> None:
    tags: dict[str, str] = {}
    await asyncio.sleep(random.uniform(0, think_s))  # readers do not all start on the same tick
    for i in range(requests):
        if i:
            await asyncio.sleep(think_s)
        path = paths[i % len(paths)]
        headers = {"If-None-Match": tags[path]} if conditional and path in tags else {}
        started = time.perf_counter()
        try:
            response = await http.get(path, headers=headers)
            status = response.status_code
        except httpx.HTTPError as exc:
            status = type(exc).__name__
        elapsed = time.perf_counter() - started
        statuses[str(status)] += 1
        if status == 200 or (status == 304 and headers):
            latencies.append(elapsed)
            if status == 304 and not_modified is not None:
                not_modified.append(elapsed)
            if "etag" in response.headers:
                tags[path] = response.headers["etag"]
        else:
            errors.append(f"{path}: {status}")


async def _load(url: str, token: str, submission_id: int, clients: int, requests: int, think_s: float,
                conditional: bool) -> dict:
    paths = [p.format(id=submission_id) for p in READS]
    latencies: list[float] = []
    not_modified: list[float] = []  # the 304s alone (conditional reads of an unchanged report)
    statuses: Counter = Counter()
    errors: list[str] = []
    limits = httpx.Limits(max_connections=clients)
    async with httpx.AsyncClient(base_url=url, headers={"Authorization": f"Bearer {token}"}, timeout=60,
                                 limits=limits) as http:
        started = time.perf_counter()
        await asyncio.gather(*(_reader(http, paths[i % 4:] + paths[:i % 4], requests, think_s, conditional,
                                       latencies, statuses, errors, not_modified) for i in range(clients)))
        wall_s = time.perf_counter() - started
    return {**latency_summary(latencies), "errors": len(errors), "error_examples": sorted(set(errors))[:5],
            "statuses": dict(statuses), "requests_per_s": sum(statuses.values()) / wall_s,
            "p95_304_ms": latency_summary(not_modified)["p95_ms"] if not_modified else None,
            "p50_304_ms": latency_summary(not_modified)["p50_ms"] if not_modified else None}


def pinning(api_cpus: str | None) -> tuple[str | None, set[int] | None, str]:
    """(the API's taskset list, the readers' CPUs, how it was arranged, in words) for `--api-cpus`: the API
    processes on those CPUs, this process (the readers) on every other one; PostgreSQL and Redis stay where the
    system puts them. Without it, nothing is pinned."""
    if not api_cpus:
        return None, None, "not pinned: the API, the readers, PostgreSQL and Redis share every core"
    mine = os.sched_getaffinity(0)
    api = {int(c) for part in api_cpus.split(",") for c in (
        range(int(part.split("-")[0]), int(part.split("-")[1]) + 1) if "-" in part else [part])}
    readers = mine - api
    if not readers:
        raise ValueError(f"--api-cpus {api_cpus} leaves no CPU for the readers (this process may use {sorted(mine)})")
    return api_cpus, readers, (f"API processes pinned to CPU {api_cpus} (taskset -c {api_cpus}), the readers to CPU "
                               f"{','.join(map(str, sorted(readers)))} (sched_setaffinity); PostgreSQL and Redis "
                               "not pinned")


def _measure_shape(stack, workers: int, submission_id: int, who: str, clients: int, requests: int, think_s: float,
                   log_dir: Path, api_cpus: str | None = None) -> dict[str, dict]:
    """Start the API as `workers` processes on the stack's database (pinned to `api_cpus`, the readers to the other
    CPUs, where given), warm it, run each mode once, stop it."""
    cpus, readers, _ = pinning(api_cpus)
    port = free_port()
    env = dict(stack.env, API_WORKERS=str(workers))
    api = start_api(env, port, log_dir / f"api-{workers}.log", workers=workers, cpus=cpus)
    before = os.sched_getaffinity(0)
    try:
        if readers:
            os.sched_setaffinity(0, readers)
        url, token = f"http://127.0.0.1:{port}", stack.tokens[who]
        # templates, pools, rubric parsing and the body cache of every process
        asyncio.run(_load(url, token, submission_id, min(clients, 4 * workers), 4, 0.0, False))
        return {mode: asyncio.run(_load(url, token, submission_id, clients, requests, think_s, mode == "conditional"))
                for mode in MODES}
    finally:
        os.sched_setaffinity(0, before)
        stop(api)


def _medians(runs: list[dict]) -> dict:
    alone = {k: median([r[k] for r in runs if r.get(k) is not None]) if any(r.get(k) is not None for r in runs)
             else None for k in ("p50_304_ms", "p95_304_ms")}
    return {**{k: median([r[k] for r in runs]) for k in SUMMARY}, **alone, "errors": sum(r["errors"] for r in runs),
            "repeats": runs}


def bench_reads(stack, submission_id: int, who: str, *, clients: int, requests: int, repeats: int, workers: int,
                think_s: float, log: Callable[[str], None] = print, api_cpus: str | None = None) -> dict:
    """One process and `workers` processes, `repeats` times each in turns, every mode; medians and ratios."""
    shapes = {"one": 1, "deployed": workers}
    runs: dict[str, dict[str, list]] = {s: {m: [] for m in MODES} for s in shapes}
    for repeat in range(repeats):
        order = list(shapes) if repeat % 2 == 0 else list(shapes)[::-1]
        for shape in order:
            got = _measure_shape(stack, shapes[shape], submission_id, who, clients, requests, think_s,
                                 stack.data_dir, api_cpus)
            for mode, figures in got.items():
                runs[shape][mode].append(figures)
                log(f"  {shape} ({shapes[shape]} process{'es' if shapes[shape] > 1 else ''}), {mode}, think "
                    f"{think_s:g} s: p50 {figures['p50_ms']:.0f} ms, p95 {figures['p95_ms']:.0f} ms, p99 "
                    f"{figures['p99_ms']:.0f} ms, {figures['requests_per_s']:.0f} req/s, {figures['errors']} errors")
    out = {"stack": stack.kind, "clients": clients, "requests_per_client": requests, "think_s": think_s,
           "repeats": repeats, "workers": shapes, "paths": list(READS), "pinning": pinning(api_cpus)[2],
           "load_average": os.getloadavg(),
           "shapes": {s: {m: _medians(runs[s][m]) for m in MODES} for s in shapes}}
    one, deployed = out["shapes"]["one"], out["shapes"]["deployed"]
    out["ratios"] = {m: {"p95_one_over_deployed": one[m]["p95_ms"] / deployed[m]["p95_ms"],
                         "requests_per_s_deployed_over_one": deployed[m]["requests_per_s"] / one[m]["requests_per_s"]}
                     for m in MODES}
    return out


def run_reads(options, services: Path, *, graded_submission, save, log) -> list[dict]:
    """The reads part of `python -m tools.bench`: one stack, one graded submission, one comparison per think time;
    the deployed shape has API_WORKERS processes (docker-compose.yml's 2 unless set)."""
    workers, rows = DEPLOYED_WORKERS, []
    with service_stack(STACK, services, students=1) as stack:
        submission_id, who = graded_submission(stack)
        stop(stack.api)  # the shapes start their own API processes; an idle one would hold database connections
        stack.env["RATE_LIMIT_STORAGE_URL"] = stack.env["BROKER_URL"]  # as deployed: counts shared through Redis
        for think in options.api_think_s:
            log(f"== reads of a graded report, {options.api_clients} clients, one process vs {workers} ({STACK}); "
                + pinning(options.api_cpus)[2])
            rows.append(bench_reads(stack, submission_id, who, clients=options.api_clients,
                                    requests=options.api_requests, repeats=options.repeats, workers=workers,
                                    think_s=think, log=log, api_cpus=options.api_cpus))
            save("reads", rows)
    return rows


def format_reads(rows: list[dict]) -> list[str]:
    """The side-by-side table, with the target (p95 <= 50 ms at 50 readers) met or missed per line."""
    lines = ["API reads of a graded report: one process vs the deployed shape (medians over repeats)",
             f"  {'shape':9s} {'procs':>5s} {'mode':11s} {'think':>5s} {'p50':>7s} {'p95':>7s} {'p99':>7s} "
             f"{'req/s':>6s} {'errors':>6s}  target p95 <= 50 ms"]
    for row in rows:
        for shape, modes in row["shapes"].items():
            for mode, f in modes.items():
                verdict = "met" if f["p95_ms"] <= 50 else f"missed by {f['p95_ms'] - 50:.0f} ms"
                lines.append(f"  {shape:9s} {row['workers'][shape]:5d} {mode:11s} {row['think_s']:5g} "
                             f"{f['p50_ms']:7.1f} {f['p95_ms']:7.1f} {f['p99_ms']:7.1f} {f['requests_per_s']:6.0f} "
                             f"{f['errors']:6d}  {verdict}")
        for mode, r in row["ratios"].items():
            lines.append(f"    {mode}, think {row['think_s']:g} s: p95 one/deployed {r['p95_one_over_deployed']:.2f}, "
                         f"req/s deployed/one {r['requests_per_s_deployed_over_one']:.2f}")
    lines += _targets(rows)
    return lines


def _targets(rows: list[dict]) -> list[str]:
    """Issue 35 item 3's lines: the target with 1 s pauses, met or missed by how much, and the back-to-back figure,
    each saying how the API's cores were arranged and the machine's load average."""
    lines = []
    for row in rows:
        clients, arranged = row["clients"], row.get("pinning", "not pinned")
        load = ", ".join(f"{x:.2f}" for x in row.get("load_average", ()))
        for shape, modes in row["shapes"].items():
            for mode, f in modes.items():
                where = f"{shape} ({row['workers'][shape]} process{'es' if row['workers'][shape] > 1 else ''}), {mode}"
                if f.get("p95_304_ms") is not None:
                    where += f"; the 304s alone p50 {f['p50_304_ms']:.1f} ms, p95 {f['p95_304_ms']:.1f} ms"
                if row["think_s"] == 1:
                    verdict = "met" if f["p95_ms"] <= 50 else f"MISSED by {f['p95_ms'] - 50:.1f} ms"
                    lines.append(f"  p95 <= 50 ms for {clients} readers with 1 s pauses: {verdict} (p95 "
                                 f"{f['p95_ms']:.1f} ms, {where})")
                elif row["think_s"] == 0:
                    lines.append(f"  back to back, {clients} readers: p95 {f['p95_ms']:.1f} ms, "
                                 f"{f['requests_per_s']:.0f} req/s ({where})")
        lines.append(f"    think {row['think_s']:g} s: {arranged}; load average at the end {load}")
    return lines
