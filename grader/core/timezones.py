"""A course's time zone: which IANA names are known, and a stored naive-UTC time as the course shows it."""

from __future__ import annotations

from datetime import UTC, datetime
from functools import lru_cache
from zoneinfo import ZoneInfo, available_timezones


# Files of the system's zoneinfo folder that are not zone names a course should pick.
NOT_ZONES = {"localtime", "posixrules", "Factory"}


@lru_cache(maxsize=1)
def _known() -> frozenset[str]:
    return frozenset(n for n in available_timezones() if n not in NOT_ZONES and not n.startswith(("posix/", "right/")))


def is_zone(name: str) -> bool:
    """An IANA zone of the system's database (no file paths, no 'localtime')."""
    return name in _known()


@lru_cache(maxsize=64)
def zone(name: str) -> ZoneInfo:
    return ZoneInfo(name)


def iso(at: datetime, timezone: str = "UTC") -> str:
    """A stored naive-UTC time as ISO 8601 in the course's zone, with its offset (and the zone's name unless UTC)."""
    shown = at.replace(tzinfo=UTC).astimezone(zone(timezone)).isoformat(timespec="seconds")
    return shown if timezone == "UTC" else f"{shown} ({timezone})"


def local(at: datetime | None, timezone: str, *, seconds: bool = False) -> str:
    """For a page: '2026-12-08 10:00 CET' (aware times are taken as they are, naive ones as UTC)."""
    if at is None:
        return "–"
    aware = at if at.tzinfo is not None else at.replace(tzinfo=UTC)
    return aware.astimezone(zone(timezone)).strftime("%Y-%m-%d %H:%M" + (":%S" if seconds else "") + " %Z")
