"""Summary statistics the benchmark reports: medians, percentiles, growth."""

from __future__ import annotations

import math
import statistics
from collections.abc import Sequence


def median(values: Sequence[float]) -> float:
    return statistics.median(values) if values else math.nan


def percentile(values: Sequence[float], q: float) -> float:
    """The q-th percentile (0-100), linear between the closest ranks; NaN for no values."""
    if not values:
        return math.nan
    ordered = sorted(values)
    rank = (len(ordered) - 1) * q / 100
    low, high = math.floor(rank), math.ceil(rank)
    return ordered[low] + (ordered[high] - ordered[low]) * (rank - low)


def latency_summary(seconds: Sequence[float]) -> dict:
    """p50/p95/p99 and max in milliseconds, with the count."""
    return {"requests": len(seconds), **{f"p{q}_ms": percentile(seconds, q) * 1000 for q in (50, 95, 99)},
            "max_ms": max(seconds) * 1000 if seconds else math.nan}


def growth_pct(first: float, last: float) -> float:
    """How much last exceeds first, in percent of first."""
    return (last - first) / first * 100 if first else math.nan
