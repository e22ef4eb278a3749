"""The API and the worker on two hosts that share nothing but the database and the broker (issue 24, item 3).

Host A (this machine's root namespaces) runs PostgreSQL, Redis and the API; host B (its own network namespace over a
veth pair, its own mount and UTS namespaces, a private tmpfs as DATA_DIR at the API's own DATA_DIR path) runs the
Celery worker: tests/integration/hosts.py says how, and what host B still reads from the shared disk (the code and
the virtual environment). The reference sheet (examples/l03/reference.yaml) is graded whole: its nine runs take
seconds on a warm case process, and a smaller sheet would leave the sheet's own runs (N5, the table exercise) and
their figures untested across hosts.
"""

from __future__ import annotations

import contextlib
import os
import re
import time
from dataclasses import dataclass
from pathlib import Path

import pytest
from sqlalchemy import make_url, select
from sqlalchemy.orm import Session

from grader.core.models import Grade
from tests import services
from tests.factories import create_people, reference_sheet
from tests.integration import hosts
from tests.integration.helpers import case_runs, events, grades_of, signed_in, submit_and_wait, wait_until
from tests.private_services import PrivatePostgres, PrivateRedis

pytestmark = [pytest.mark.integration, pytest.mark.slow]

SHOTS = Path(os.environ.get("TWO_HOSTS_SHOTS", "/tmp/shots/twohost"))
EVIDENCE_FILES = ("arrays.npz", "provenance.json", "metrics.json", "spec.json", "stdout.txt", "stderr.txt")


@dataclass
class TwoHosts:
    """The deployment: the API's URL on host A, the database as host A reaches it, host B's worker (replaced when
    the test restarts host B)."""

    url: str
    tokens: dict[str, str]
    engine: object
    env: dict
    data_dir: Path
    logs: Path
    link: hosts.Link
    worker: object

    def client(self, who: str = "alice"):
        from grader.client import Client

        return Client(self.url, self.tokens[who])

    def restart_host_b(self, log_name: str) -> None:
        """Host B comes back (a fresh tmpfs: its disk is gone) and starts its worker again."""
        self.worker = hosts.start_worker_on_host_b(self.link, self.env, "cpu,grade", self.logs / log_name)


@pytest.fixture(scope="module")
def two_hosts(tmp_path_factory, kernel_cache_filled):
    from grader.core.db import make_engine, migrate

    hosts.require_root()
    base = tmp_path_factory.mktemp("two-hosts")
    data_dir, logs = base / "data", base / "logs"
    data_dir.mkdir()
    logs.mkdir()
    with contextlib.ExitStack() as cleanup:
        link = cleanup.enter_context(hosts.veth_link())
        redis = PrivateRedis(logs, address=link.address_a)
        redis.start()
        cleanup.callback(redis.stop)
        postgres = PrivatePostgres(address=link.address_a)
        postgres.start()
        cleanup.callback(postgres.stop)
        migrate(postgres.url)
        engine = make_engine(postgres.url)
        cleanup.callback(engine.dispose)
        with Session(engine) as session:
            tokens = create_people(session, course="l03-test", other_course="other-course")
            session.commit()
        env = {k: v for k, v in os.environ.items() if k != "ARTIFACTS_DIR"}  # both hosts derive it from DATA_DIR
        env |= dict(DATABASE_URL=postgres.url, BROKER_URL=redis.url, DATA_DIR=str(data_dir), CASE_TIME_LIMIT_S="600",
                    PYTHONPATH=str(services.ROOT), RATE_LIMIT_SUBMISSIONS="1000/minute",
                    STUDENT_WAITING_RUNS_MAX="1000")
        port = services.free_port()
        api = services.start_api(env, port, logs / "api.log")
        cleanup.callback(services.stop, api)
        deployment = TwoHosts(f"http://127.0.0.1:{port}", tokens, engine, env, data_dir, logs, link, None)
        started = time.monotonic()
        deployment.restart_host_b("worker-b-1.log")
        print(f"\nhost B's worker ready in {time.monotonic() - started:.1f} s")
        cleanup.callback(lambda: hosts.kill_host_b(deployment.worker))  # its kernel cache is its own: no lock left
        yield deployment


def completed(two_hosts, submission_id: int) -> bool:
    """The grade's figures and lab check are done (worker.grading.complete_grade set completed_at)."""
    with Session(two_hosts.engine) as session:
        return session.scalar(select(Grade.completed_at).where(Grade.submission_id == submission_id)) is not None


@pytest.fixture(scope="module")
def graded(two_hosts) -> dict:
    """Alice's reference sheet, measured and graded by host B's worker, its report complete."""
    started = time.monotonic()
    _, final = submit_and_wait(two_hosts, reference_sheet(), who="alice")
    assert final["status"] == "graded", final
    wait_until(lambda: completed(two_hosts, final["id"]), "the report's figures and lab check")
    print(f"\nthe reference sheet graded on host B, report complete, in {time.monotonic() - started:.1f} s")
    return final


def test_a_submission_is_measured_and_graded_on_host_b(two_hosts, graded):
    runs = case_runs(two_hosts, graded["id"])
    assert len(runs) == 9 and all(run.status == "done" and run.reused_from_id is None for run in runs)
    # host B reaches the database and the broker over the veth only: not host A's loopback, where the API listens
    link, port = two_hosts.link, int(two_hosts.url.rsplit(":", 1)[1])
    assert hosts.reaches_from_host_b(link, link.address_a, make_url(two_hosts.env["DATABASE_URL"]).port)
    assert not hosts.reaches_from_host_b(link, "127.0.0.1", port)
    assert {run.worker for run in runs} == {hosts.HOST_B}  # claimed on host B, by hostname
    assert {run.provenance["host"] for run in runs} == {hosts.HOST_B}
    assert grades_of(two_hosts, graded["id"]) == 1
    with Session(two_hosts.engine) as session:
        check = session.scalar(select(Grade).where(Grade.submission_id == graded["id"])).report["check"]
    # drawn on host B over its own ARTIFACTS_DIR, stored with the grade for host A to show
    assert check["verdict_line"] == "L03 CHECK: PASSED", check


def test_the_report_page_and_every_download_load_from_the_api(browser, two_hosts, graded):
    submission = graded["id"]
    page = signed_in_as_alice(browser, two_hosts)
    assert page.goto(f"{two_hosts.url}/submissions/{submission}").status == 200
    page.wait_for_selector("#case-runs", state="attached")
    evidence = page.locator("p.downloads a").evaluate_all("els => els.map(a => a.getAttribute('href'))")
    assert len(evidence) == 9 * len(EVIDENCE_FILES), evidence  # every run's evidence, all six files
    downloads = page.locator(f"a[href^='/submissions/{submission}/']").evaluate_all(
        "els => els.map(a => a.getAttribute('href'))")  # results.json, the charts' data links too
    failed = {url: status for url in dict.fromkeys([*downloads, *referenced_media(page)])
              if (status := page.request.get(f"{two_hosts.url}{url}").status) != 200}
    assert not failed, failed
    client = two_hosts.client("alice")
    for run in client.case_runs(submission):
        for name in EVIDENCE_FILES:
            body = client.http.get(f"/submissions/{submission}/case-runs/{run['name']}/files/{name}")
            assert body.status_code == 200, (run["name"], name, body.status_code)
            assert body.content or name in ("stdout.txt", "stderr.txt"), (run["name"], name)  # output may be empty
    SHOTS.mkdir(parents=True, exist_ok=True)
    page.screenshot(path=SHOTS / "report_from_host_a.png", full_page=True)


def signed_in_as_alice(browser, two_hosts):
    page = signed_in(browser, two_hosts, "alice")
    page.wait_for_url(f"{two_hosts.url}/submissions")  # the sign-in's redirect, before the next navigation
    return page


def referenced_media(page) -> list[str]:
    """Every `img src` and `data-src` of the page (the PNG figures, or the charts' data when drawn in the browser)."""
    return page.locator("img[src], [data-src]").evaluate_all(
        "els => els.map(e => e.getAttribute('data-src') || e.getAttribute('src'))")


def test_the_report_shows_its_figures_from_the_api(browser, two_hosts, graded):
    page = signed_in_as_alice(browser, two_hosts)
    page.goto(f"{two_hosts.url}/submissions/{graded['id']}")
    page.wait_for_selector("#case-runs", state="attached")
    figures = [url for url in referenced_media(page) if re.search(r"/figures?/|/charts?/|series", url)]
    assert len(figures) >= 5, f"the report references {len(figures)} figures: {figures}"
    failed = {url: status for url in dict.fromkeys(figures)
              if (status := page.request.get(f"{two_hosts.url}{url}").status) != 200}
    assert not failed, failed
    SHOTS.mkdir(parents=True, exist_ok=True)
    page.locator("#figures").scroll_into_view_if_needed()
    page.screenshot(path=SHOTS / "report_figures_from_host_a.png")


def test_the_api_host_holds_no_file_the_worker_wrote(two_hosts, graded):
    """Same DATA_DIR path on both hosts: host B's copy holds the runs' folders, host A's nothing at all."""
    on_b = hosts.files_on_host_b(two_hosts.worker, two_hosts.data_dir)
    for run in case_runs(two_hosts, graded["id"]):
        assert f"artifacts/case-runs/{run.id}/try-1/arrays.npz" in on_b, (run.name, on_b[:20])
    assert hosts.files_on_host_a(two_hosts.data_dir) == []


def test_host_b_killed_mid_case_is_recovered_as_on_one_host(two_hosts, graded):
    """SIGKILL of host B's whole worker mid-case (its tmpfs goes with it): host B comes back with an empty disk, its
    worker re-sends the run its dead process held (worker.tasks._rerun_what_died_here, by hostname), and the
    submission is graded once, from evidence in the database, the earlier runs' folders being gone."""
    client = two_hosts.client("eve")  # force_rerun is a staff power; eve teaches the other course
    created = client.submit(reference_sheet() | {"student": "eve"}, force_rerun=True)

    def running_with_evidence():
        for run in case_runs(two_hosts, created["id"]):
            if run.status == "running" and run.worker_pid and run.tries == 1:
                folder = two_hosts.data_dir / "artifacts" / "case-runs" / str(run.id) / "try-1"
                if f"{folder.relative_to(two_hosts.data_dir)}/spec.json" in hosts.files_on_host_b(
                        two_hosts.worker, two_hosts.data_dir):
                    return run
        return None

    victim = wait_until(running_with_evidence, "a case run in the middle of its case on host B")
    done_before = [run.id for run in case_runs(two_hosts, created["id"]) if run.status == "done"]
    hosts.kill_host_b(two_hosts.worker)
    killed = time.monotonic()
    two_hosts.restart_host_b("worker-b-2.log")
    print(f"\nhost B back (worker ready) {time.monotonic() - killed:.1f} s after the SIGKILL")

    final = client.wait(created["id"], poll_s=0.5, timeout_s=900)
    print(f"graded {time.monotonic() - killed:.1f} s after the SIGKILL")
    assert final["status"] == "graded", final
    after = {run.id: run for run in case_runs(two_hosts, created["id"])}
    assert after[victim.id].status == "done" and after[victim.id].tries == 2
    assert after[victim.id].reused_from_id is None and after[victim.id].worker == hosts.HOST_B
    states = [e.state for e in events(two_hosts, created["id"]) if e.case_run_id == victim.id]
    assert states.count("running") == 2 and "requeued" in states and states[-1] == "done"
    assert [e.state for e in events(two_hosts, created["id"])].count("graded") == 1
    assert grades_of(two_hosts, created["id"]) == 1
    on_b = hosts.files_on_host_b(two_hosts.worker, two_hosts.data_dir)
    lost = [run_id for run_id in done_before if any(f"case-runs/{run_id}/" in f for f in on_b)]
    assert not lost, "host B's restarted disk should not hold the runs measured before the kill"
    assert hosts.files_on_host_a(two_hosts.data_dir) == []
