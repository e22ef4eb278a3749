"""A variant pool being measured never holds a student's runs back (issue 44): on the real broker (Redis, as deployed,
and the embedded filesystem broker), with the Celery app sending as grader.dispatch does, a pool's runs queued first
and a student's submission after them, a worker whose slots free one by one claims every one of the student's runs
before the rest of the pool; the student waits only for the pool runs already on a slot. The service is the real app
in-process (tests/grader/conftest.py), the claims the worker's own (grader.core.lifecycle.claim)."""

from __future__ import annotations

import pytest
from kombu import Connection
from kombu.transport.virtual import BrokerState
from sqlalchemy import select

from tests import services
from tests.factories import reference_sheet
from tests.grader.conftest import app_on
from tests.grader.services.setup.test_variants import generate, pool_assignment

pytestmark = pytest.mark.integration

SLOTS = 2  # the worker's case slots: with prefetch 1 and late acks it holds one message per slot


@pytest.fixture(params=["redis", "filesystem"])
def broker(request, tmp_path, monkeypatch):
    """A connection to an empty broker with the transport options the Celery app uses for it."""
    from worker.celery_app import transport_options

    if request.param == "redis":
        client = services.redis_client()  # fails under CI=true when Redis is missing
        url, options = services.SPARE_REDIS_URL, transport_options(services.SPARE_REDIS_URL)
    else:
        from kombu.transport import filesystem

        # each test its own folder, so its own bindings (tests/worker/test_filesystem_broker.py)
        monkeypatch.setattr(filesystem.Transport, "global_state", BrokerState())
        folder = tmp_path / "broker"
        url, options = "filesystem://", {"data_folder_in": str(folder), "data_folder_out": str(folder),
                                         "control_folder": str(folder / "control"), "polling_interval": 0.05}
        folder.mkdir()
    with Connection(url, transport_options=options) as connection:
        queue = connection.SimpleQueue("cpu")
        queue.clear()
        yield connection, queue
        queue.clear()
        queue.close()
    if request.param == "redis":
        client.connection_pool.disconnect()


def test_a_students_runs_are_claimed_before_the_rest_of_a_pool_queued_before_them(broker, tmp_path, monkeypatch):
    from grader import dispatch
    from grader.core.db import new_session
    from grader.core.lifecycle import claim
    from grader.core.models import CaseRun, Submission
    from grader.services.identity import accounts
    from grader.services.submissions.progress import queue_order
    from worker.celery_app import RUN_TASK, app

    connection, queue = broker

    def send_case_run(case_run_id, delivery, backend, *, priority=dispatch.NEW_PRIORITY):
        """grader.dispatch.send_case_run, on this test's broker."""
        app.send_task(RUN_TASK, args=[case_run_id, delivery], queue=backend, priority=priority, connection=connection)

    def take() -> int:
        """A slot frees: the worker takes the next message and claims its run, as worker.tasks.run_case_run does."""
        message = queue.get(timeout=5)
        case_run_id, delivery = message.decode()[0]
        message.ack()
        with new_session() as session:
            run, _ = claim(session=session, case_run_id=case_run_id, delivery=delivery)
            assert run is not None, f"case run {case_run_id} delivery {delivery} not claimable"
            session.commit()
        return case_run_id

    with app_on(f"sqlite:///{tmp_path / 'grader.db'}", tmp_path, monkeypatch) as api:
        monkeypatch.setattr(dispatch, "send_case_run", send_case_run)
        with new_session() as session:  # a student of another course than the pool's
            other = accounts.get_or_create_course(session=session, name="other")
            sam = accounts.get_or_create_user(session=session, course=other, name="sam", role="student")
            api.tokens["sam"] = accounts.create_token(session=session, user=sam)
            session.commit()

        pooled = generate(api, pool_assignment(api), k=3)
        assert pooled.status_code == 201, pooled.text
        first = [take() for _ in range(SLOTS)]  # the pool's first runs hold both slots
        submitted = api.client.post("/v1/submissions", json={"sheet": reference_sheet()}, headers=api.as_("sam"))
        assert submitted.status_code == 202, submitted.text
        with new_session() as session:
            runs = session.execute(select(CaseRun.id, Submission.student_id, Submission.id)
                                   .join(Submission, CaseRun.submission_id == Submission.id)).all()
            students = {run_id: sub_id == submitted.json()["id"] for run_id, _, sub_id in runs}
            predicted = queue_order(session, "cpu")  # what a progress page tells the student
        assert sum(students.values()) == 9 and len(students) == 9 + 3 * 9
        assert not any(students[i] for i in first)

        order = [take() for _ in range(len(students) - SLOTS)]
        theirs = [students[i] for i in order]
        # each slot that frees takes one of the student's runs until none is left: the pool's resume after them
        assert theirs == [True] * 9 + [False] * (3 * 9 - SLOTS), theirs
        assert predicted == order
