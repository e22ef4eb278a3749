"""The one clock the service dates things by: naive UTC "now", shifted for a rehearsal or frozen by a test.

Every service, page, worker and the reconciler reads `now()` (also `grader.core.models.utcnow`, the name the tables'
defaults and the services import), never the system clock, so that:
- a test pins "now" to an instant of its own (`frozen(at)`; in the suite, `@pytest.mark.clock("...")`) and its
  literal due, open and close times mean the same thing on every calendar day;
- a whole deployment or test run can live as if on another date: `CLOCK_SHIFT_DAYS=365 make test` runs the suite a
  year ahead (settings.clock_shift_days, read by every process, API, workers and CLI alike, from the environment).
Durations (rate-limit windows, timeouts, measured run times) keep reading `time.monotonic`/`time.time`: they measure
elapsed time, they do not date anything.
"""

from __future__ import annotations

import threading
from collections.abc import Iterator
from contextlib import contextmanager
from datetime import UTC, datetime, timedelta

from grader.core.settings import settings

__all__ = ["frozen", "now", "parse_instant"]

_lock = threading.Lock()
_frozen: datetime | None = None


def now() -> datetime:
    """The current instant, naive UTC (the form every timestamp column stores)."""
    frozen_at = _frozen
    if frozen_at is not None:
        return frozen_at
    return datetime.now(UTC).replace(tzinfo=None) + timedelta(days=settings.clock_shift_days)


def parse_instant(value: str | datetime) -> datetime:
    """An ISO 8601 instant with its offset (or an aware datetime) as naive UTC; a naive value is refused."""
    at = datetime.fromisoformat(value.replace("Z", "+00:00")) if isinstance(value, str) else value
    if at.tzinfo is None:
        raise ValueError(f"{value!r}: an instant needs its UTC offset")
    return at.astimezone(UTC).replace(tzinfo=None)


@contextmanager
def frozen(at: str | datetime) -> Iterator[datetime]:
    """Within the block, `now()` answers `at` in this process (every thread), whatever the calendar says."""
    global _frozen
    instant = parse_instant(at)
    with _lock:
        before, _frozen = _frozen, instant
    try:
        yield instant
    finally:
        with _lock:
            _frozen = before
