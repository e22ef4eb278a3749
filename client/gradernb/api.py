"""The service's HTTP API, signed in with a student's token: assignments, sheets, drafts, checks, submissions."""

from __future__ import annotations

import os
from typing import Any

import httpx

from gradernb import views


class GraderError(RuntimeError):
    """A refusal by the service: its `status`, `detail` and `errors` ({field, rule, words} each), said in words."""

    def __init__(self, status: int, detail: str, errors: list[dict] | None = None):
        self.status, self.detail, self.errors = status, detail, errors or []
        lines = [f"{detail} (HTTP {status})"] + [f"  {e.get('words') or e.get('field', '')}: {e.get('rule', '')}"
                                                 for e in self.errors]
        super().__init__("\n".join(lines))


class Grader:
    """One signed-in student (or instructor) of one service. `language`: "en" or "zh" for questions and words."""

    def __init__(self, url: str, token: str, *, language: str = "en", timeout: float = 30.0):
        self.url, self.language, self.token = url.rstrip("/"), language, token
        self.http = httpx.Client(base_url=self.url + "/v1", headers={"Authorization": f"Bearer {token}"},
                                 timeout=timeout)

    def call(self, method: str, path: str, **kwargs) -> Any:
        response = self.http.request(method, path, **kwargs)
        if response.is_error:
            try:
                body = response.json()
            except ValueError:
                body = {"detail": response.text[:500]}
            detail = body.get("detail") if isinstance(body.get("detail"), str) else str(body.get("detail"))
            raise GraderError(response.status_code, detail, body.get("errors"))
        return response.json()

    def assignments(self) -> views.Table:
        """Your course's assignments: id, title, phase (open, late, upcoming, closed), due date, attempts, your lab."""
        rows = self.call("GET", "/sheets", params={"language": self.language})
        return views.Table(["id", "title", "lesson", "part", "phase", "due_at", "attempts_left", "lab"], rows,
                           title="Your assignments")

    def sheet(self, assignment_id: int):
        """The sheet of one assignment: its items, your own lab, your saved draft (the page's), your standing."""
        from gradernb.sheet import Sheet  # sheet imports this module

        data = self.call("GET", f"/assignments/{assignment_id}/sheet", params={"language": self.language})
        return Sheet(self, data)

    def submission(self, submission_id: int):
        from gradernb.sheet import Submission

        return Submission(self, self.call("GET", f"/submissions/{submission_id}"))


def connect(url: str | None = None, token: str | None = None, *, link: str | None = None,
            language: str = "en") -> Grader:
    """Sign in with your token (from your instructor, or `GRADER_TOKEN`), or with your sign-in link (`link=`, the
    whole `https://.../sign-in/link/...`: it is used up, as pressing its button is, and the notebook gets a token
    for 7 days; keep `grader.token` to sign in again). `url` is the service (or `GRADER_URL`; a link names it). The
    token is checked at once: a wrong or revoked one is said here, not at the first submission."""
    if link is not None:
        base, _, secret = link.rstrip("/").partition("/sign-in/link/")
        if not secret:
            raise GraderError(0, "a sign-in link looks like https://SERVICE/sign-in/link/SECRET")
        url = url or base
        response = httpx.post(f"{url.rstrip('/')}/v1/sign-in-links/{secret}/token", timeout=30.0)
        if response.is_error:
            raise GraderError(response.status_code, response.json().get("detail", response.text[:300])
                              if "json" in response.headers.get("content-type", "") else response.text[:300])
        token = response.json()["token"]
    url = url or os.environ.get("GRADER_URL")
    token = token or os.environ.get("GRADER_TOKEN")
    if not url or not token:
        raise GraderError(0, "connect needs the service's address and your token (or GRADER_URL and GRADER_TOKEN)")
    grader = Grader(url, token, language=language)
    grader.call("GET", "/submissions")  # 401 here names an unknown, revoked or expired token
    return grader
