"""Session-wide fixtures: every baseline case measured once on real Genesis (CPU), shared by all test packages."""

from __future__ import annotations

import os
import tempfile

import pytest

# Settings are read at import; without this, importing the Celery app would create the embedded broker's folders
# under the repository's var/ during tests. Tests that need their own data dir still set DATA_DIR themselves.
os.environ.setdefault("DATA_DIR", tempfile.mkdtemp(prefix="grader-tests-"))

from rubric import BASELINE_CASES, CaseResult
from worker import run_cases


@pytest.fixture(autouse=True)
def _clock(request):
    """`@pytest.mark.clock("2026-11-20T12:00:00Z")` freezes the service's clock (grader.core.clock) at that instant
    for the test, so its literal due, open and close times keep their meaning on any calendar day
    (tests/test_dates.py refuses a literal date in a test without one)."""
    marker = request.node.get_closest_marker("clock")
    if marker is None:
        yield None
        return
    from grader.core import clock

    with clock.frozen(marker.args[0]) as at:
        yield at


@pytest.fixture(scope="session")
def measured(tmp_path_factory) -> dict[str, CaseResult]:
    """N1-N5 and both friction runs, measured once per session in one warm Genesis process."""
    out = tmp_path_factory.mktemp("measured")
    results = run_cases(BASELINE_CASES.values(), out, mode="warm")
    failed = {name: r.error for name, r in results.items() if not r.ok}
    assert not failed, f"baseline cases failed on real Genesis: {failed}"
    return results
