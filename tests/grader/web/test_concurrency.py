"""Many concurrent readers: the API never waits on its own database pool (sized to its threads and admitted
requests), so 50 clients reading at once all get answers, quickly, instead of 30 s pool timeouts."""

from __future__ import annotations

import threading
import time

import pytest

from tests.factories import reference_sheet

CLIENTS = 50
READS_EACH = 4
# A safety stop well under SQLAlchemy's 30 s pool timeout: exhausting the pool shows as a hang, not a slow answer.
LIMIT_S = 20


@pytest.mark.timeout(90)
def test_fifty_concurrent_readers_all_get_answers(api, monkeypatch):
    from fastapi.testclient import TestClient

    from grader.main import app
    from grader.core.settings import settings

    # Fifty clients, though in-process they share one address: its per-client cap must not refuse them.
    monkeypatch.setattr(settings, "client_max_in_flight", CLIENTS)

    created = api.client.post("/v1/submissions", json={"sheet": reference_sheet()}, headers=api.as_("alice"))
    assert created.status_code == 202, created.text
    submission_id = created.json()["id"]
    _graded(submission_id)  # the report page of a graded submission also reads its rubric version
    paths = [f"/v1/submissions/{submission_id}", f"/submissions/{submission_id}"]
    statuses: list[int] = []
    # One event loop for every request (the `with` block), as under uvicorn: one thread pool, one database pool.
    with TestClient(app) as client:
        barrier = threading.Barrier(CLIENTS)

        def reader(i: int) -> None:
            barrier.wait()
            for j in range(READS_EACH):
                statuses.append(client.get(paths[(i + j) % 2], headers=api.as_("alice")).status_code)

        threads = [threading.Thread(target=reader, args=(i,), daemon=True) for i in range(CLIENTS)]
        started = time.monotonic()
        for t in threads:
            t.start()
        for t in threads:
            t.join(max(0.0, LIMIT_S - (time.monotonic() - started)))
        # Inside the block: leaving it waits for every request, which a dry pool answers only after its timeout.
        assert len(statuses) == CLIENTS * READS_EACH, f"{len(statuses)} answers in {LIMIT_S} s: the pool ran dry"
    assert set(statuses) == {200}


def _graded(submission_id: int) -> None:
    from rubric.scoring import GradeReport

    from grader.core.db import new_session
    from grader.core.models import Grade, Submission

    report = GradeReport(lesson="L03", student="alice", rubric_version="2", rubric_hash="x", engine_version="1.3.3",
                         total=0, max_total=0, complete=True, items=[], config_findings=[])
    with new_session() as session:
        session.add(Grade(submission_id=submission_id, rubric_lesson="L03", rubric_version="2", rubric_hash="x",
                          total=0, max_total=0, report=report.model_dump(mode="json")))
        session.get(Submission, submission_id).status = "graded"
        session.commit()


def test_the_pool_holds_a_connection_for_every_admitted_request(tmp_path):
    from grader.core.db import make_engine
    from grader.core.settings import settings

    engine = make_engine(f"sqlite:///{tmp_path / 'p.db'}")
    try:
        assert engine.pool.size() >= settings.api_threads
    finally:
        engine.dispose()
