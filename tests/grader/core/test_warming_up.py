"""While no worker on a run's queue is warm and one is warming up, the progress page says the service is warming up
and how long that took last time; /metrics and `grader status` show each worker's slots, warm and warming
(grader.core.warmth, written by worker.warm_gate; here written as a worker would, on the embedded broker's store)."""

from __future__ import annotations

import time

import pytest
from click.testing import CliRunner

from grader.cli.service import status
from grader.core import warmth
from tests.factories import reference_sheet


@pytest.fixture
def a_worker(api, tmp_path, monkeypatch):
    """A worker's record, as worker.warm_gate writes it, in a broker store of this test's own: a worker another test
    of this process started (or killed) within the last RECORD_TTL_S would otherwise count here too."""
    monkeypatch.setattr(warmth.settings, "data_dir", tmp_path / "data")
    monkeypatch.setattr(warmth.settings, "broker_url", "filesystem://")
    name = f"cpu-grade-test-{time.monotonic_ns()}@host"
    yield lambda warm, consuming, queues=("cpu", "grade"): warmth.record(warmth.WorkerWarmth(
        name=name, queues=tuple(queues), slots=2, warm=warm, started_at=time.time() - 30,
        warm_s=12.5 if consuming else None))
    warmth.forget(name)


def test_the_progress_page_says_the_service_is_warming_up_until_a_worker_on_its_queue_is_warm(api, a_worker):
    created = api.client.post("/v1/submissions", headers=api.as_("alice"),
                              json={"sheet": reference_sheet() | {"student": "alice"}})
    assert created.status_code == 202, created.text
    page_url = f"/submissions/{created.json()['id']}/progress"
    assert 'id="warming-up"' not in api.client.get(page_url, headers=api.as_("alice")).text  # no worker known

    warmth.record_warm_up(83.0)
    a_worker(warm=1, consuming=False)
    page = api.client.get(page_url, headers=api.as_("alice")).text
    assert 'id="warming-up"' in page and "The service is warming up" in page
    assert "Warming up took 1 min 23 s last time." in page
    polled = api.client.get(page_url + ".json", headers=api.as_("alice")).json()
    assert polled["warming_up"]["last_s"] == 83.0 and polled["warming_up"]["for_s"] >= 29
    assert 'id="warming-up"' in polled["html"]

    a_worker(warm=2, consuming=True)
    assert 'id="warming-up"' not in api.client.get(page_url, headers=api.as_("alice")).text
    a_worker(warm=0, consuming=False, queues=("rocm",))  # warming on another queue: not what this submission waits on
    assert 'id="warming-up"' not in api.client.get(page_url, headers=api.as_("alice")).text


def test_metrics_and_grader_status_show_warm_and_warming_slots(api, a_worker):
    warmth.record_warm_up(83.0)
    a_worker(warm=1, consuming=False)
    metrics = api.client.get("/metrics").text
    worker = warmth.live()[0].name
    assert f'grader_worker_slots{{state="warm",worker="{worker}"}} 1.0' in metrics
    assert f'grader_worker_slots{{state="warming",worker="{worker}"}} 1.0' in metrics
    assert f'grader_worker_consuming_cases{{worker="{worker}"}} 0.0' in metrics
    assert "grader_last_warm_up_seconds 83.0" in metrics
    out = CliRunner().invoke(status, []).output
    assert f"{worker}: 1 of 2 case slots warm, WARMING UP for" in out and "last warm-up: 83.0 s" in out

    a_worker(warm=2, consuming=True)
    assert f'grader_worker_consuming_cases{{worker="{worker}"}} 1.0' in api.client.get("/metrics").text
    assert f"{worker}: 2 of 2 case slots warm, taking cases (warmed up in 12.5 s)" in CliRunner().invoke(status).output
