"""`grader worker --healthy`, the worker container's health check (issue 46): a ping that also says the warm gate's
state. A worker that answers but still warms up takes no case, so it is not healthy yet; one whose warm gate stopped
renewing its record is not either. The ping is replaced here (no broker with broadcast); the container test
(tests/integration/test_containers.py) runs the real one in every worker container."""

from __future__ import annotations

import os
import socket
import time

from click.testing import CliRunner

from grader import ops
from grader.cli import service
from grader.core import warmth

NODE = f"cpu-grade@{socket.gethostname()}"  # `grader worker`'s own name for its default queues, cpu and grade


def _health(monkeypatch, tmp_path, *, answered, **record):
    monkeypatch.setattr(warmth.settings, "data_dir", tmp_path)
    monkeypatch.setattr(warmth.settings, "broker_url", "filesystem://")
    asked = []

    def ping(node, timeout_s):
        asked.append(node)
        if isinstance(answered, Exception):
            raise answered
        return answered

    monkeypatch.setattr(ops, "_ping", ping)
    if record:
        warmth.record(warmth.WorkerWarmth(name=NODE, queues=("cpu", "grade"), **record))
    result = CliRunner().invoke(service.worker, ["--healthy"])
    assert asked == [NODE], asked
    return result


def test_a_warm_worker_that_answers_is_healthy_and_says_its_slots(monkeypatch, tmp_path):
    result = _health(monkeypatch, tmp_path, answered=True, slots=2, warm=2, started_at=time.time() - 90, warm_s=84.0)
    assert result.exit_code == 0, result.output
    assert result.output.strip() == f"healthy: {NODE} answered; 2 of 2 case slots warm, taking cases (warmed up in " \
                                    "84.0 s)"


def test_a_worker_still_warming_up_is_not_healthy_yet(monkeypatch, tmp_path):
    result = _health(monkeypatch, tmp_path, answered=True, slots=2, warm=1, started_at=time.time() - 40)
    assert result.exit_code == 1, result.output
    assert f"unhealthy: {NODE} is warming up, 1 of 2 case slots warm after 40 s; it takes no case yet" in result.output


def test_a_worker_that_does_not_answer_is_unhealthy_whatever_its_record(monkeypatch, tmp_path):
    result = _health(monkeypatch, tmp_path, answered=False, slots=1, warm=1, started_at=time.time(), warm_s=1.0)
    assert result.exit_code == 1 and f"unhealthy: {NODE} did not answer a ping within 10 s" in result.output, \
        result.output


def test_a_worker_whose_record_lapsed_is_unhealthy(monkeypatch, tmp_path):
    result = _health(monkeypatch, tmp_path, answered=True)
    assert result.exit_code == 1 and f"unhealthy: {NODE} renewed no warm-up record within 15 s" in result.output, \
        result.output
    # A record last renewed longer ago than its lifetime: its warm gate stopped (the same as none).
    warmth.record(warmth.WorkerWarmth(name=NODE, queues=("cpu",), slots=1, warm=1, started_at=time.time(), warm_s=1.0))
    stale = time.time() - warmth.RECORD_TTL_S - 1
    os.utime(tmp_path / "broker" / "warmth" / f"{NODE}.json", (stale, stale))
    lapsed = CliRunner().invoke(service.worker, ["--healthy"])
    assert lapsed.exit_code == 1 and "renewed no warm-up record" in lapsed.output, lapsed.output


def test_a_broker_that_does_not_answer_makes_the_worker_unhealthy(monkeypatch, tmp_path):
    result = _health(monkeypatch, tmp_path, answered=ConnectionError("Error 111 connecting to redis:6379"))
    assert result.exit_code == 1, result.output
    assert "unhealthy: the broker did not answer (ConnectionError: Error 111 connecting to redis:6379)" in result.output
