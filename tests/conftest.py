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


# tryfirst: pytest-xdist's worker plugin reads the xdist_group markers in its own pytest_collection_modifyitems, so
# the markers added here must be there before it runs (registered after this conftest, it ran first).
@pytest.hookimpl(tryfirst=True)
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
    if getattr(config.option, "loadgroup", False):  # an xdist test process under --dist loadgroup
        for item in items:
            _group_in_nodeid(item)


def _group_in_nodeid(item) -> None:
    """Append "@group" to the item's nodeid, which is how xdist's loadgroup scheduler learns an item's group.

    pytest-xdist 3.8 does it by setting `item._nodeid`, but pytest 9.2's `nodeid` reads `item._id` (a NodeId): its
    suffix was lost and no group ever formed, so every module was scheduled test by test. 2026-12-07, `make test`'s
    schedule: test_discrepancy's 64-bit runs and test_case_process's isolated runs were each built on both test
    processes, and the three "variants" modules ran their stack on both. Done here the way xdist means it."""
    groups = sorted({str(mark.args[0] if mark.args else mark.kwargs.get("name", "default"))
                     for mark in item.iter_markers("xdist_group")})
    if not groups or item.nodeid.endswith("@" + "_".join(groups)) or not hasattr(item, "_id"):
        return  # no group; already suffixed; or a pytest whose nodeid xdist's own suffix reaches
    from _pytest.nodeid import NodeId

    item._id = NodeId.parse(f"{item.nodeid}@{'_'.join(groups)}")


@pytest.fixture(scope="session")
def measured(tmp_path_factory, worker_id) -> dict[str, CaseResult]:
    """N1-N5 and both friction runs, measured once per test run in one warm Genesis process.

    Under pytest-xdist the first test process to need them measures them into a folder all processes share, under a
    file lock; the others wait for it and read the very same runs back through `load_result`, which checks each one
    as it checked the first time (arrays, provenance, discretization): one measurement, never a substitute."""
    return _shared_runs(tmp_path_factory, worker_id, "measured", list(BASELINE_CASES.values()), mode="warm")


@pytest.fixture(scope="session")
def isolated_contact(tmp_path_factory, worker_id) -> dict[str, CaseResult]:
    """N1-N4, each in its own fresh process (the lesson's contract), two at a time: once per test run, shared as
    `measured` is. tests/worker/test_case_process and tests/rubric/test_discrepancy each ran these four processes for
    their own module (2026-12-07: 60-100 s of CPU each time on the 2-core machine)."""
    from rubric import CONTACT_CASES, get_case

    return _shared_runs(tmp_path_factory, worker_id, "isolated", [get_case(n) for n in CONTACT_CASES],
                        mode="isolated", jobs=2)


@pytest.fixture(scope="session")
def rendered_n1(tmp_path_factory, worker_id) -> CaseResult:
    """N1 on cpu with rendering, in a fresh process: once per test run, shared as `measured` is. tests/worker/
    test_case_process (real frames on a headless machine) and tests/worker/test_figures (the camera figure) each ran
    this very run for themselves (20-45 s each on the loaded 2-core machine)."""
    from rubric import get_case, with_backend

    spec = with_backend(get_case("N1"), backend="cpu", render=True)
    return _shared_runs(tmp_path_factory, worker_id, "rendered", [spec], mode="isolated")["N1"]


@pytest.fixture(scope="session")
def l02_measured(tmp_path_factory, worker_id) -> dict[str, CaseResult]:
    """L02's runs of its reference sheet (S1, S2 and the exercise's config as sheet.exercise), measured once per test
    run in one warm Genesis process, shared as `measured` is."""
    from pathlib import Path

    import yaml

    from rubric import cases_to_run, parse_sheet

    examples = Path(__file__).resolve().parents[1] / "examples"
    sheet = parse_sheet(yaml.safe_load((examples / "l02" / "reference.yaml").read_text()))
    return _shared_runs(tmp_path_factory, worker_id, "l02", cases_to_run(sheet), mode="warm")


def _shared_runs(tmp_path_factory, worker_id, name: str, specs: list, *, mode: str, jobs: int = 1):
    """Run `specs` once per test run (see `measured`); every run must succeed on real Genesis."""
    from filelock import FileLock

    from worker.case_process import load_result

    if worker_id == "master":
        return _runs_into(tmp_path_factory.mktemp(name), specs, mode, jobs)
    shared = tmp_path_factory.getbasetemp().parent / name
    with FileLock(str(shared) + ".lock"):
        done = shared / "done.json"
        if not done.exists():
            results = _runs_into(shared, specs, mode, jobs)
            done.write_text(json.dumps({name: r.wall_s for name, r in results.items()}))
            return results
    walls = json.loads(done.read_text())
    results = {spec.name: load_result(spec, shared / spec.name, exit_status=0, mode=mode, wall_s=walls[spec.name])
               for spec in specs}
    failed = {name: r.error for name, r in results.items() if not r.ok}
    assert not failed, f"cases run by another test process do not read back: {failed}"
    return results


def _runs_into(out, specs: list, mode: str, jobs: int) -> dict[str, CaseResult]:
    results = run_cases(specs, out, mode=mode, jobs=jobs)
    failed = {name: r.error for name, r in results.items() if not r.ok}
    assert not failed, f"cases failed on real Genesis: {failed}"
    return results
