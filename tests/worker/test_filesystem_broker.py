"""The embedded broker serves a queue by priority, lowest number first, then in the order sent (as Redis does)."""

from __future__ import annotations

import os

import pytest
from kombu import Connection
from kombu.transport.virtual import BrokerState


@pytest.fixture(autouse=True)
def fresh_broker_state(monkeypatch):
    """kombu keeps the filesystem transport's declared bindings in one class-level state per process, written to a
    folder's control files only on first declaration: a later test's new folder would get no binding for a queue an
    earlier test declared, and its messages would go nowhere. A service process has one folder; each test here has
    its own, so each gets its own state."""
    from kombu.transport import filesystem

    monkeypatch.setattr(filesystem.Transport, "global_state", BrokerState())


def test_a_resent_run_is_read_before_the_runs_queued_earlier(tmp_path):
    import worker.celery_app  # noqa: F401 - makes filesystem:// this project's transport
    from grader.dispatch import NEW_PRIORITY, REQUEUED_PRIORITY, RERUN_PRIORITY
    from worker.filesystem_broker import Transport

    folder = str(tmp_path)
    options = {"data_folder_in": folder, "data_folder_out": folder, "control_folder": str(tmp_path / "control")}
    with Connection("filesystem://", transport_options=options) as connection:
        assert isinstance(connection.transport, Transport)
        queue = connection.SimpleQueue("cpu")
        for body, priority in (("new 1", NEW_PRIORITY), ("requeued", REQUEUED_PRIORITY), ("new 2", NEW_PRIORITY),
                               ("rerun", RERUN_PRIORITY), ("new 3", NEW_PRIORITY)):
            queue.put(body, priority=priority)
        connection.SimpleQueue("grade").put("a grade task")
        assert queue.qsize() == 5  # kombu still counts (and purges) a queue's files by the name after the first dot
        read = []
        for _ in range(5):
            message = queue.get(timeout=1)
            read.append(message.payload)
            message.ack()
        assert read == ["rerun", "requeued", "new 1", "new 2", "new 3"]
        assert connection.SimpleQueue("grade").get(timeout=1).payload == "a grade task"


def test_a_grades_lab_check_is_read_after_every_case_run_queued_before_or_after_it(tmp_path):
    """The completion of a stored grade waits on the cpu queue behind the case runs (worker.celery_app): at a deadline
    a worker measures every waiting case, and so stores every grade, before it evaluates a lab check."""
    import worker.celery_app  # noqa: F401 - makes filesystem:// this project's transport
    from grader.core.lifecycle import COMPLETE_PRIORITY, NEW_PRIORITY, REQUEUED_PRIORITY, RERUN_PRIORITY
    from worker.celery_app import COMPLETE_QUEUE

    folder = str(tmp_path)
    options = {"data_folder_in": folder, "data_folder_out": folder, "control_folder": str(tmp_path / "control")}
    with Connection("filesystem://", transport_options=options) as connection:
        queue = connection.SimpleQueue(COMPLETE_QUEUE)
        for body, priority in (("lab check of grade 1", COMPLETE_PRIORITY), ("new run", NEW_PRIORITY),
                               ("lab check of grade 2", COMPLETE_PRIORITY), ("requeued run", REQUEUED_PRIORITY),
                               ("rerun", RERUN_PRIORITY), ("newer run", NEW_PRIORITY)):
            queue.put(body, priority=priority)
        read = []
        for _ in range(6):
            message = queue.get(timeout=1)
            read.append(message.payload)
            message.ack()
        assert read == ["rerun", "requeued run", "new run", "newer run", "lab check of grade 1",
                        "lab check of grade 2"]


def test_a_message_file_appears_only_once_written(tmp_path, monkeypatch):
    """A reader lists the folder and takes any '<x>.<queue>.msg' it finds: a message must never be visible under
    that name before its bytes are in it (the benchmark saw a worker die on an empty file it read mid-write)."""
    import builtins

    import worker.filesystem_broker as broker

    opened_for_writing = []

    def spy(path, mode="r", *args, **kwargs):
        if "w" in mode:
            opened_for_writing.append(os.path.basename(path))
        return builtins.open(path, mode, *args, **kwargs)

    monkeypatch.setattr(broker, "open", spy, raising=False)
    folder = str(tmp_path)
    options = {"data_folder_in": folder, "data_folder_out": folder, "control_folder": str(tmp_path / "control")}
    with Connection(transport=broker.Transport, transport_options=options) as connection:
        queue = connection.SimpleQueue("written")
        queue.put({"case": "N1"})
        assert opened_for_writing and not any(name.endswith(".msg") for name in opened_for_writing)
        assert [name for name in os.listdir(folder) if name.endswith(".part")] == []
        assert queue.get(timeout=1).payload == {"case": "N1"}
