"""Session-wide fixtures: every baseline case measured once on real Genesis (CPU), shared by all test packages."""

from __future__ import annotations

import json
import os
import tempfile

import pytest

# Settings are read at import; without this, importing the Celery app would create the embedded broker's folders
# under the repository's var/ during tests. Tests that need their own data dir still set DATA_DIR themselves.
os.environ.setdefault("DATA_DIR", tempfile.mkdtemp(prefix="grader-tests-"))
# Every worker a test starts has one case slot (one warm Genesis process) unless the test asks for more
# (tests/integration/test_parallel_cases.py does): the suite already runs a test process per core, and a slot per core
# in each of the dozens of workers it starts would double the Genesis warm-ups competing for the same two cores.
os.environ.setdefault("WORKER_CONCURRENCY", "1")

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


def pytest_addoption(parser):
    parser.addoption("--shuffle-seed", type=int, default=None, metavar="N",
                     help="run the tests in a random order drawn from seed N: the modules shuffled, and the tests "
                          "within each module (as pytest-randomly orders them; the same N gives the same order)")


def pytest_report_header(config):
    seed = config.getoption("--shuffle-seed")
    return None if seed is None else f"tests shuffled with --shuffle-seed={seed}"


def pytest_collection_modifyitems(config, items):
    """Under pytest-xdist (`make test`: --dist loadgroup), a module with an `integration` or `slow` test stays whole on
    one test process: its tests share module fixtures (a second host, a private broker, a browser walk's pages, runs
    at 64-bit precision or in isolated processes) that are costly to build twice. Scheduled one by one, a module's
    tests went to both processes or were split by other modules, and its module fixture was built again each time
    (2026-11-27: tests/rubric/test_discrepancy's 64-bit runs twice, 81 s and 74 s; tests/worker/test_case_process's
    runs twice, 41 s each). Every other test is scheduled on its own, wherever a process is free.

    `--shuffle-seed=N` reorders them first (issue 37: no test may depend on the order or on another test's rows).
    A module's tests stay together, so module fixtures are built once; every xdist process draws the same order from
    the same seed, as xdist requires, and loadgroup hands out the groups in that shuffled order.

    Unshuffled, the modules that wait on real services or run Genesis (an `integration` or `slow` test among them) go
    first, the many short ones after, so the short ones fill both processes at the end rather than one long module
    running alone (longest first). `make test` passes --no-loadscope-reorder: xdist's own reordering would sort the
    groups by their number of tests instead, which puts single long tests (the container stack, the isolated Genesis
    runs) among the short ones."""
    seed = config.getoption("--shuffle-seed")
    heavy = {item.path for item in items if item.get_closest_marker("integration") or item.get_closest_marker("slow")}
    if seed is None:
        items.sort(key=lambda item: item.path not in heavy)  # stable: the order within each part is kept
    else:
        import random

        rng = random.Random(seed)
        modules: dict[object, list] = {}
        for item in items:
            modules.setdefault(item.path, []).append(item)
        buckets = list(modules.values())
        rng.shuffle(buckets)
        for bucket in buckets:
            rng.shuffle(bucket)
        items[:] = [item for bucket in buckets for item in bucket]
    for item in items:
        if item.path in heavy and not item.get_closest_marker("xdist_group"):
            name = item.path.stem if "integration" in item.path.parts else str(item.path.relative_to(config.rootpath))
            item.add_marker(pytest.mark.xdist_group(name))


@pytest.fixture(scope="session")
def measured(tmp_path_factory, worker_id) -> dict[str, CaseResult]:
    """N1-N5 and both friction runs, measured once per test run in one warm Genesis process.

    Under pytest-xdist the first test process to need them measures them into a folder all processes share, under a
    file lock; the others wait for it and read the very same runs back through `load_result`, which checks each one
    as it checked the first time (arrays, provenance, discretization): one measurement, never a substitute."""
    from filelock import FileLock

    from worker.case_process import load_result

    if worker_id == "master":
        out = tmp_path_factory.mktemp("measured")
        return _measured_into(out)
    shared = tmp_path_factory.getbasetemp().parent / "measured"
    with FileLock(str(shared) + ".lock"):
        done = shared / "done.json"
        if not done.exists():
            results = _measured_into(shared)
            done.write_text(json.dumps({name: r.wall_s for name, r in results.items()}))
            return results
    walls = json.loads(done.read_text())
    results = {name: load_result(spec, shared / name, exit_status=0, mode="warm", wall_s=walls[name])
               for name, spec in BASELINE_CASES.items()}
    failed = {name: r.error for name, r in results.items() if not r.ok}
    assert not failed, f"baseline cases measured by another test process do not read back: {failed}"
    return results


def _measured_into(out) -> dict[str, CaseResult]:
    results = run_cases(BASELINE_CASES.values(), out, mode="warm")
    failed = {name: r.error for name, r in results.items() if not r.ok}
    assert not failed, f"baseline cases failed on real Genesis: {failed}"
    return results
