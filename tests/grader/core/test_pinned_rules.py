"""Pins hourly Retry-After, staff visibility, after_due timing, best-attempt ties, the reuse key's runner version."""

from __future__ import annotations

from datetime import UTC, datetime, timedelta

from grader.core import clock
# The content key's home (it was worker/reuse.py): if it moves again, re-point this one import.
from grader.core import content_key as content_keys

CHECKPOINTS = ("C1", "C2", "C3", "C4", "C5", "C6", "C7", "C8")


def utcnow() -> datetime:
    """Now as the service stores times: naive UTC, from its one clock (grader.core.clock)."""
    return clock.now()


def at(days: float = 0, hours: float = 0) -> str:
    """An instant relative to the service's now, ISO 8601 with its offset."""
    return (clock.now().replace(microsecond=0, tzinfo=UTC) + timedelta(days=days, hours=hours)).isoformat()


def create_assignment(api, **over) -> int:
    body = {"title": "Checkpoints", "part": "checkpoints", "open_at": at(-1), "due_at": at(1), "hard_close_at": at(3),
            **over}
    response = api.client.post("/v1/courses/l03/assignments", json=body, headers=api.as_("prof"))
    assert response.status_code == 201, response.text
    return response.json()["id"]


def checkpoint_sheet(student: str) -> dict:
    from rubric.sheet import CHECKPOINT_IDS
    from tests.factories import reference_sheet

    sheet = reference_sheet()
    return {"lesson": "L03", "student": student,
            "answers": {k: v for k, v in sheet["answers"].items() if k in CHECKPOINT_IDS}}


def submit(api, assignment_id: int, who: str = "alice"):
    """A checkpoint sheet for the assignment; no lesson case was measured here, so its cases are only queued."""
    return api.client.post("/v1/submissions", json={"sheet": checkpoint_sheet(who), "assignment_id": assignment_id},
                           headers=api.as_(who))


def grade(submission_id: int, scores: dict[str, float]) -> None:
    """Store a grade for the submission as the worker would, with the given per-item scores (1 point each)."""
    from grader.core.db import new_session
    from grader.core.models import Grade, Submission
    from rubric.scoring import GradeReport, ItemGrade

    items = [ItemGrade(id=i, question=f"question {i}", part="checkpoint", kind="conceptual", points=1, score=s,
                       max_score=1, verdict="credit" if s else "no_credit", prediction="{}", expected="",
                       feedback=f"feedback on {i}", evidence={}, backends={}, tolerances={})
             for i, s in scores.items()]
    report = GradeReport(lesson="L03", student="alice", rubric_version="2", rubric_hash="x", engine_version="1.3.3",
                         total=sum(scores.values()), max_total=len(scores), complete=True, items=items,
                         config_findings=[])
    with new_session() as session:
        session.add(Grade(submission_id=submission_id, rubric_lesson="L03", rubric_version="2", rubric_hash="x",
                          total=report.total, max_total=report.max_total, report=report.model_dump(mode="json")))
        row = session.get(Submission, submission_id)
        row.status, row.graded_at = "graded", utcnow()
        session.commit()


def graded_submission(api, assignment_id: int, scores: dict[str, float] | None = None) -> int:
    response = submit(api, assignment_id)
    assert response.status_code == 202, response.text
    sid = response.json()["id"]
    grade(sid, scores or dict.fromkeys(CHECKPOINTS, 1.0))
    return sid


def set_assignment(assignment_id: int, **values) -> None:
    from grader.core.db import new_session
    from grader.core.models import Assignment

    with new_session() as session:
        row = session.get(Assignment, assignment_id)
        for k, v in values.items():
            setattr(row, k, v)
        session.commit()


def shown(api, sid: int, who: str) -> dict[str, float | None]:
    response = api.client.get(f"/v1/submissions/{sid}/grade", headers=api.as_(who))
    assert response.status_code == 200, (who, response.text)
    return {i["id"]: i["score"] for i in response.json()["items"]}


# --- 1. the hourly limit's Retry-After counts from the oldest submission in the window --------------------------

def test_retry_after_counts_from_the_oldest_submission_that_fills_the_hour(api):
    from grader.core.db import new_session
    from grader.core.models import Submission

    aid = create_assignment(api, max_per_hour=2)
    ids = [submit(api, aid).json()["id"] for _ in range(2)]
    now = utcnow()
    with new_session() as session:  # the first 50 minutes ago, the second 10 minutes ago
        for sid, minutes in zip(ids, (50, 10)):
            session.get(Submission, sid).created_at = now - timedelta(minutes=minutes)
        session.commit()
    third = submit(api, aid)
    assert third.status_code == 429, third.text
    # A place frees when the 50-minute-old one turns an hour old: in about 10 minutes, not 50.
    assert 540 <= int(third.headers["Retry-After"]) <= 601, third.headers["Retry-After"]
    (err,) = third.json()["errors"]
    expected = (now - timedelta(minutes=50) + timedelta(hours=1)).replace(microsecond=0)
    assert any(f"{(expected + timedelta(seconds=s)).isoformat()}+00:00" in err["rule"] for s in (0, 1, 2)), err


# --- 2. staff (instructors and auditors) see every item -----------------------------------------------------------

def test_an_auditor_sees_every_item_a_student_has_withheld(api):
    aid = create_assignment(api, item_visibility={"C2": "on_release", "C3": "after_due"})
    sid = graded_submission(api, aid)
    student = shown(api, sid, "alice")
    assert student["C2"] is None and student["C3"] is None and student["C4"] == 1.0
    for staff in ("tess", "prof"):
        assert shown(api, sid, staff) == dict.fromkeys(CHECKPOINTS, 1.0), staff
        body = api.client.get(f"/v1/submissions/{sid}/grade", headers=api.as_(staff)).json()
        assert body["pending"] is None and body["total"] == 8
        row = api.client.get(f"/v1/submissions/{sid}", headers=api.as_(staff)).json()
        assert row["pending"] is None and row["total"] == 8


def test_an_auditor_reads_a_grade_withheld_whole_from_the_student(api):
    aid = create_assignment(api, visibility="on_release")
    sid = graded_submission(api, aid)
    assert api.client.get(f"/v1/submissions/{sid}/grade", headers=api.as_("alice")).status_code == 409
    assert shown(api, sid, "tess") == dict.fromkeys(CHECKPOINTS, 1.0)
    assert api.client.get(f"/v1/submissions/{sid}/grades", headers=api.as_("tess")).status_code == 200


# --- 3. after_due items are shown from the due date on, not later --------------------------------------------------

def test_an_after_due_item_is_withheld_just_before_the_due_date_and_shown_seconds_after(api):
    aid = create_assignment(api, item_visibility={"C4": "after_due"})
    sid = graded_submission(api, aid)
    set_assignment(aid, due_at=utcnow() + timedelta(seconds=60))
    before = shown(api, sid, "alice")
    assert before["C4"] is None and before["C3"] == 1.0
    set_assignment(aid, due_at=utcnow() - timedelta(seconds=5))
    assert shown(api, sid, "alice") == dict.fromkeys(CHECKPOINTS, 1.0)


def test_a_grade_withheld_whole_until_the_due_date_is_shown_minutes_after_it(api):
    aid = create_assignment(api, visibility="after_due")
    sid = graded_submission(api, aid)
    set_assignment(aid, due_at=utcnow() + timedelta(minutes=2))
    assert api.client.get(f"/v1/submissions/{sid}/grade", headers=api.as_("alice")).status_code == 409
    set_assignment(aid, due_at=utcnow() - timedelta(minutes=2))
    assert shown(api, sid, "alice") == dict.fromkeys(CHECKPOINTS, 1.0)
    row = api.client.get(f"/v1/submissions/{sid}", headers=api.as_("alice")).json()
    assert (row["total"], row["pending"]) == (8, None)


# --- 4. under counted_attempt=best, a tie goes to the later attempt ------------------------------------------------

def test_a_tie_for_best_counts_the_later_attempt(api):
    aid = create_assignment(api, counted_attempt="best")
    scores = dict.fromkeys(CHECKPOINTS, 1.0) | {"C2": 0.0}
    first, second = graded_submission(api, aid, scores), graded_submission(api, aid, scores)
    listed = {s["id"]: s["counts"] for s in api.client.get("/v1/submissions", headers=api.as_("alice")).json()}
    assert listed == {first: False, second: True}
    for sid, counts in ((first, False), (second, True)):
        row = api.client.get(f"/v1/submissions/{sid}", headers=api.as_("prof")).json()
        assert (row["counted_score"], row["counts"]) == (7, counts)
    grades = api.client.get(f"/v1/assignments/{aid}/grades", headers=api.as_("prof"))
    assert grades.status_code == 200, grades.text
    assert [(g["submission_id"], g["attempt"], g["counted_score"]) for g in grades.json()] == [(second, 2, 7)]


def test_a_better_earlier_attempt_still_counts_under_best(api):
    aid = create_assignment(api, counted_attempt="best")
    first = graded_submission(api, aid)
    second = graded_submission(api, aid, dict.fromkeys(CHECKPOINTS, 1.0) | {"C2": 0.0})
    listed = {s["id"]: s["counts"] for s in api.client.get("/v1/submissions", headers=api.as_("alice")).json()}
    assert listed == {first: True, second: False}


# --- 5. the reuse key holds the runner version ---------------------------------------------------------------------

def test_the_runner_version_is_part_of_the_reuse_key(monkeypatch):
    import rubric.results
    from rubric import get_case

    spec = get_case("N1").model_dump(mode="json", exclude_computed_fields=True)
    inputs = content_keys.key_inputs(spec, backend="cpu", precision="32")
    assert inputs["runner_version"] == rubric.results.RUNNER_VERSION
    before = content_keys.content_key(inputs)
    monkeypatch.setattr(rubric.results, "RUNNER_VERSION", rubric.results.RUNNER_VERSION + ".next")
    after = content_keys.key_inputs(spec, backend="cpu", precision="32")
    assert after["runner_version"] == rubric.results.RUNNER_VERSION
    assert content_keys.content_key(after) != before
    monkeypatch.undo()
    assert content_keys.content_key(content_keys.key_inputs(spec, backend="cpu", precision="32")) == before

