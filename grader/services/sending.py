"""What the services need of the task queue, as a protocol: the web layer and the command line pass
`grader.dispatch` (Celery), tests pass a recorder. Services never import Celery."""

from __future__ import annotations

from typing import Protocol


class Sender(Protocol):
    def send_case_run(self, case_run_id: int, delivery: int, backend: str, *, priority: int = ...) -> None: ...

    def send_grade(self, submission_id: int) -> None: ...

    def queue_listeners(self, backend: str) -> list[str]: ...
