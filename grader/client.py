"""A small HTTP client of the grading API: submit a sheet file, follow its progress, fetch the grade."""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path

import httpx

from grader.core.states import SubmissionState
from rubric import sheet_files


def load_sheet(path: Path) -> dict:
    """A sheet from .yaml/.yml or .json; rubric.sheet_files.SheetTextError naming the field of a number the service
    cannot hold (as the sheet page's import does), before anything is sent."""
    text = path.read_text()
    return sheet_files.load_yaml(text) if path.suffix in (".yaml", ".yml") else sheet_files.load_json(text)


# The longest a poll waits on one 429's Retry-After (the API's own limits ask for seconds; a minute at most).
MAX_RETRY_AFTER_S = 60.0


class ApiError(RuntimeError):
    """An error answer: `status`, and `retry_after` (seconds) where the API said when to come back."""

    def __init__(self, message: str, *, status: int, retry_after: float | None):
        super().__init__(message)
        self.status, self.retry_after = status, retry_after


def _retry_after(response: httpx.Response) -> float | None:
    try:  # the API writes seconds (grader.web.admission, grader.services.identity.quotas), never an HTTP date
        return min(max(float(response.headers["retry-after"]), 0.0), MAX_RETRY_AFTER_S)
    except (KeyError, ValueError):
        return None


class Client:
    def __init__(self, url: str, token: str, *, timeout: float = 30.0):
        self.http = httpx.Client(base_url=url.rstrip("/") + "/v1", headers={"Authorization": f"Bearer {token}"},
                                 timeout=timeout)

    def _ok(self, response: httpx.Response) -> dict | list:
        if response.is_error:
            body = response.json() if "json" in response.headers.get("content-type", "") else {"detail": response.text}
            lines = [body.get("detail", "")] + [f"  {e['field']}: {e['rule']}" for e in body.get("errors", [])]
            raise ApiError(f"HTTP {response.status_code}: " + "\n".join(lines), status=response.status_code,
                          retry_after=_retry_after(response))
        return response.json()

    def submit(self, sheet: dict, **options) -> dict:
        return self._ok(self.http.post("/submissions", json={"sheet": sheet, **options}))

    def submission(self, submission_id: int) -> dict:
        return self._ok(self.http.get(f"/submissions/{submission_id}"))

    def grade(self, submission_id: int) -> dict:
        return self._ok(self.http.get(f"/submissions/{submission_id}/grade"))

    def case_runs(self, submission_id: int) -> list:
        return self._ok(self.http.get(f"/submissions/{submission_id}/case-runs"))

    def events(self, submission_id: int) -> list:
        return self._ok(self.http.get(f"/submissions/{submission_id}/events"))

    def dashboard(self, course: str) -> dict:
        return self._ok(self.http.get(f"/courses/{course}/dashboard"))

    def grade_history(self, submission_id: int) -> list:
        return self._ok(self.http.get(f"/submissions/{submission_id}/grades"))

    def rubric_versions(self, lesson: str = "L03") -> list:
        return self._ok(self.http.get(f"/rubrics/{lesson}/versions"))

    def publish_rubric(self, content: dict) -> dict:
        return self._ok(self.http.post("/rubrics/versions", json=content))

    def regrade_preview(self, course: str, version: str, lesson: str = "L03") -> dict:
        return self._ok(self.http.get(f"/courses/{course}/regrade-preview", params={"version": version, "lesson": lesson}))

    def commit_regrade(self, course: str, version: str, content_hash: str, lesson: str = "L03") -> dict:
        body = {"version": version, "lesson": lesson, "content_hash": content_hash}
        return self._ok(self.http.post(f"/courses/{course}/regrades", json=body))

    def create_assignment(self, course: str, body: dict) -> dict:
        return self._ok(self.http.post(f"/courses/{course}/assignments", json=body))

    def assignments(self, course: str) -> list:
        return self._ok(self.http.get(f"/courses/{course}/assignments"))

    def assignment(self, assignment_id: int) -> dict:
        return self._ok(self.http.get(f"/assignments/{assignment_id}"))

    def generate_variants(self, assignment_id: int, body: dict) -> dict:
        return self._ok(self.http.post(f"/assignments/{assignment_id}/variants", json=body))

    def top_up_variants(self, assignment_id: int, more: int | None = None) -> dict:
        body = {"more": more} if more is not None else None
        return self._ok(self.http.post(f"/assignments/{assignment_id}/variants/top-up", json=body))

    def variants(self, assignment_id: int) -> dict:
        return self._ok(self.http.get(f"/assignments/{assignment_id}/variants"))

    def copy_flags(self, assignment_id: int) -> list:
        return self._ok(self.http.get(f"/assignments/{assignment_id}/copy-flags"))

    def release(self, assignment_id: int) -> dict:
        return self._ok(self.http.post(f"/assignments/{assignment_id}/release"))

    def extend(self, assignment_id: int, body: dict) -> dict:
        return self._ok(self.http.post(f"/assignments/{assignment_id}/extensions", json=body))

    def counted_grades(self, assignment_id: int) -> list:
        return self._ok(self.http.get(f"/assignments/{assignment_id}/grades"))

    def counted_grades_csv(self, assignment_id: int) -> str:
        response = self.http.get(f"/assignments/{assignment_id}/grades.csv")
        if response.is_error:
            self._ok(response)
        return response.text

    def course(self, course: str) -> dict:
        return self._ok(self.http.get(f"/courses/{course}"))

    def update_course(self, course: str, body: dict) -> dict:
        return self._ok(self.http.patch(f"/courses/{course}", json=body))

    def import_roster(self, course: str, csv_text: str, links: bool = False) -> list:
        return self._ok(self.http.post(f"/courses/{course}/roster", json={"csv": csv_text, "links": links}))

    def sign_in_link(self, course: str, student: str) -> dict:
        return self._ok(self.http.post(f"/courses/{course}/students/{student}/sign-in-link"))

    def wait(self, submission_id: int, *, poll_s: float = 1.0, on_progress: Callable[[dict], None] | None = None,
             timeout_s: float | None = None, complete: bool = True) -> dict:
        """Poll until failed, or graded with its report complete (its lab check stored; `complete=False`:
        graded is enough); on_progress gets every status body. A poll refused with 429 (this address's requests in
        flight, while other clients of the same address stall theirs) is waited out as its Retry-After says, never
        taken for the submission's end."""
        deadline = None if timeout_s is None else time.monotonic() + timeout_s
        while True:
            try:
                state = self.submission(submission_id)
            except ApiError as refused:
                if refused.status != 429:
                    raise
                wait_s = refused.retry_after if refused.retry_after is not None else poll_s
                if deadline is not None and time.monotonic() + wait_s > deadline:
                    raise TimeoutError(f"submission {submission_id}: its status refused (429) until the timeout, "
                                       f"{timeout_s} s") from None
                time.sleep(wait_s)
                continue
            if on_progress:
                on_progress(state)
            if state["status"] == SubmissionState.FAILED or (state["status"] == SubmissionState.GRADED
                                               and (not complete or state.get("report_complete") is not False)):
                return state
            if deadline is not None and time.monotonic() > deadline:
                raise TimeoutError(f"submission {submission_id} still {state['status']} after {timeout_s} s")
            time.sleep(poll_s)
