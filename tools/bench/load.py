"""API latency under concurrent readers: N clients on loopback, each reading a graded submission and its report
page in turn, a bounded number of requests each (an httpx script: no load tool to install). Back to back (think 0:
the service's worst case) or each reader pausing `think_s` between reads, like a student refreshing a page."""

from __future__ import annotations

import asyncio
import random
import time
from collections.abc import Callable

import httpx

from tools.bench.stats import latency_summary

# What a student refreshing their result reads: the submission (status, progress) and the report page.
PATHS = ("/v1/submissions/{id}", "/submissions/{id}")


async def _client(url: str, token: str, paths: list[str], requests: int, latencies: dict, errors: list,
                  think_s: float = 0.0) -> None:
    async with httpx.AsyncClient(base_url=url, headers={"Authorization": f"Bearer {token}"}, timeout=60) as http:
        await asyncio.sleep(random.uniform(0, think_s))  # readers do not all start on the same tick
        for i in range(requests):
            if i:
                await asyncio.sleep(think_s)
            path = paths[i % len(paths)]
            started = time.perf_counter()
            try:
                response = await http.get(path)
                status = response.status_code
            except httpx.HTTPError as exc:
                status = type(exc).__name__
            elapsed = time.perf_counter() - started
            if status == 200:
                latencies[path].append(elapsed)
            else:
                errors.append(f"{path}: {status}")


async def _load(url: str, token: str, submission_id: int, clients: int, requests: int,
                think_s: float = 0.0) -> tuple[dict, list, float]:
    paths = [p.format(id=submission_id) for p in PATHS]
    latencies: dict[str, list[float]] = {p: [] for p in paths}
    errors: list[str] = []
    started = time.perf_counter()
    await asyncio.gather(*(_client(url, token, paths[i % 2:] + paths[:i % 2], requests, latencies, errors,
                                   think_s) for i in range(clients)))
    return latencies, errors, time.perf_counter() - started


def bench_api(stack, submission_id: int, who: str, clients: int, requests: int, think_s: float = 0.0,
              log: Callable[[str], None] = print) -> dict:
    """`clients` concurrent clients, `requests` each, after one warm-up round of the same; latencies of 200s only,
    every other answer counted as an error."""
    token = stack.tokens[who]
    asyncio.run(_load(stack.url, token, submission_id, min(clients, 5), 4))  # templates, pool, caches
    latencies, errors, wall_s = asyncio.run(_load(stack.url, token, submission_id, clients, requests, think_s))
    every = [s for values in latencies.values() for s in values]
    figures = {"stack": stack.kind, "clients": clients, "requests_per_client": requests, "think_s": think_s,
               **latency_summary(every), "errors": len(errors), "error_examples": sorted(set(errors))[:5],
               "requests_per_s": (len(every) + len(errors)) / wall_s,
               "by_path": {pattern: latency_summary(latencies[pattern.format(id=submission_id)]) for pattern in PATHS}}
    log(f"  {clients} clients (think {think_s:g} s) on {stack.kind}: p50 {figures['p50_ms']:.0f} ms, "
        f"p95 {figures['p95_ms']:.0f} ms, p99 {figures['p99_ms']:.0f} ms, {figures['errors']} errors, "
        f"{figures['requests_per_s']:.0f} req/s")
    return figures
