"""On the real Redis broker, with the transport options the Celery app uses, students' runs come off a queue
interleaved by their fair priorities (grader.core.lifecycle.fair_priority), not first come, first served."""

from __future__ import annotations

import pytest
from kombu import Connection

from tests import services

pytestmark = pytest.mark.integration

QUEUE = "fair-queue-test"


@pytest.fixture
def redis_url():
    client = services.redis_client()  # fails under CI=true when Redis is missing
    url = services.SPARE_REDIS_URL
    yield url
    client.connection_pool.disconnect()


def read_all(url: str, sent: list[tuple[str, int]]) -> list[str]:
    from worker.celery_app import transport_options

    with Connection(url, transport_options=transport_options(url)) as connection:
        queue = connection.SimpleQueue(QUEUE)
        queue.clear()
        for body, priority in sent:
            queue.put(body, priority=priority)
        read = []
        for _ in sent:
            message = queue.get(timeout=2)
            read.append(message.payload)
            message.ack()
        queue.close()
    return read


def test_a_student_with_one_run_waiting_is_served_before_the_backlog_of_another(redis_url):
    from grader.core.lifecycle import REQUEUED_PRIORITY, fair_priority

    # alice queues nine runs, then bob nine, then carol one, then a lost run of alice's is re-sent
    sent = [(f"alice {i}", fair_priority(i - 1)) for i in range(1, 10)]
    sent += [(f"bob {i}", fair_priority(i - 1)) for i in range(1, 10)]
    sent += [("carol 1", fair_priority(0)), ("alice 0 (requeued)", REQUEUED_PRIORITY)]
    read = read_all(redis_url, sent)
    assert read[:10] == ["alice 0 (requeued)", "alice 1", "bob 1", "carol 1", "alice 2", "bob 2", "alice 3", "bob 3",
                         "alice 4", "bob 4"]
    assert read[10:] == [f"alice {i}" for i in range(5, 10)] + [f"bob {i}" for i in range(5, 10)]
