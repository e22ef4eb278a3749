"""Per-item visibility, counted grades on each submission and the hourly limit, on the in-process app (SQLite)."""

from __future__ import annotations

import re

import pytest

from tests.grader.services.setup.test_assignments import assignment_count, at, checkpoint_sheet, create, submit
from tests.grader.services.setup.test_assignments import lesson_cases_stored  # noqa: F401 - autouse: the lesson measured


def test_item_visibility_must_name_items_of_the_assignment_nothing_stored(api):
    response = create(api, item_visibility={"C3": "on_release", "A1": "after_due"})
    assert response.status_code == 422, response.text
    (err,) = response.json()["errors"]
    assert err["field"] == "item_visibility.A1" and "not an item of this assignment (checkpoints: C1," in err["rule"]
    bad = create(api, item_visibility={"C3": "never"})
    assert bad.status_code == 422 and bad.json()["errors"][0]["field"] == "item_visibility.C3"
    assert assignment_count() == 0


def test_a_withheld_item_is_hidden_everywhere_a_student_looks_then_shown_on_release_with_the_same_score(api):
    aid = create(api, item_visibility={"C2": "on_release", "C3": "on_release"}).json()
    assert aid["item_visibility"] == {"C2": "on_release", "C3": "on_release"}
    sid = submit(api, aid["id"]).json()["id"]
    staff = api.client.get(f"/v1/submissions/{sid}/grade", headers=api.as_("prof")).json()
    scores = {i["id"]: i["score"] for i in staff["items"]}
    # The student: C2 and C3 pending, the other six shown; the total counts what is shown and says the rest is pending.
    grade = api.client.get(f"/v1/submissions/{sid}/grade", headers=api.as_("alice"))
    assert grade.status_code == 200, grade.text
    items = {i["id"]: i for i in grade.json()["items"]}
    assert items["C2"]["score"] is None and items["C2"]["verdict"] == "pending"
    assert "released by an instructor" in items["C2"]["feedback"] and items["C2"]["evidence"] is None
    assert items["C4"]["score"] == scores["C4"]
    shown_total = sum(v for k, v in scores.items() if k not in ("C2", "C3"))
    assert grade.json()["total"] == shown_total and grade.json()["max_total"] == 8
    assert grade.json()["pending"].startswith("2 of 8 points pending (C2, C3)")
    row = api.client.get(f"/v1/submissions/{sid}", headers=api.as_("alice")).json()
    assert (row["total"], row["raw_score"], row["counted_score"]) == (shown_total, None, None)
    assert row["counts"] is True and "C2, C3" in row["pending"]
    assert api.client.get(f"/v1/submissions/{sid}/grades", headers=api.as_("alice")).status_code == 409
    page = api.client.get(f"/submissions/{sid}", headers=api.as_("alice")).text
    assert 'verdict-pending">pending<' in page and "2 of 8 points pending" in page
    assert "withheld: shown once “" in page and "” is released by an instructor" in page
    results = api.client.get(f"/submissions/{sid}/results.json", headers=api.as_("alice")).json()
    assert {i["id"]: i["score"] for i in results["items"]}["C3"] is None and results["total"] == shown_total
    listing = api.client.get("/submissions", headers=api.as_("alice")).text
    assert "part pending" in listing
    # Released: the same stored grade, every item shown, nothing regraded.
    assert api.client.post(f"/v1/assignments/{aid['id']}/release", headers=api.as_("prof")).status_code == 200
    after = api.client.get(f"/v1/submissions/{sid}/grade", headers=api.as_("alice")).json()
    assert {i["id"]: i["score"] for i in after["items"]} == scores and after["pending"] is None
    assert after["total"] == staff["total"] and after["created_at"] == staff["created_at"]
    row = api.client.get(f"/v1/submissions/{sid}", headers=api.as_("alice")).json()
    assert (row["raw_score"], row["penalty"], row["counted_score"], row["pending"]) == (staff["total"], 0, staff["total"],
                                                                                      None)


def test_an_item_shown_at_once_in_an_assignment_withheld_until_the_due_date(api):
    aid = create(api, visibility="after_due", item_visibility={"C2": "immediate"}).json()["id"]
    sid = submit(api, aid).json()["id"]
    items = {i["id"]: i for i in api.client.get(f"/v1/submissions/{sid}/grade", headers=api.as_("alice")).json()["items"]}
    assert items["C2"]["verdict"] == "credit" and items["C4"]["score"] is None
    assert "shown after the due date, 20" in items["C4"]["feedback"]


def test_the_gradescope_export_carries_each_items_visibility(api):
    aid = create(api, visibility="after_due", item_visibility={"C2": "immediate", "C3": "on_release"}).json()["id"]
    sid = submit(api, aid).json()["id"]
    results = api.client.get(f"/v1/submissions/{sid}/gradescope.json", headers=api.as_("prof")).json()
    shown = {t["name"].split(":")[0]: t["visibility"] for t in results["tests"]}
    assert shown == {"C1": "after_due_date", "C2": "visible", "C3": "after_published", "C4": "after_due_date",
                     "C5": "after_due_date", "C6": "after_due_date", "C7": "after_due_date", "C8": "after_due_date"}


def test_the_gradescope_export_hides_what_another_assignment_of_the_lesson_withholds(api):
    """Issue 44 (hostile pass 2, F3): a practice attempt's export marked C1-C8 visible while an exam of the same
    checkpoints withholds them until released; Gradescope would have shown them. They were then given the exam's
    gates, but those are the practice's own Gradescope due date and publish (pass 11): they are hidden."""
    create(api, title="Exam", visibility="on_release", item_visibility={"C2": "after_due"})
    practice = create(api, title="Practice").json()["id"]
    sid = submit(api, practice).json()["id"]
    results = api.client.get(f"/v1/submissions/{sid}/gradescope.json", headers=api.as_("prof")).json()
    shown = {t["name"].split(":")[0]: t["visibility"] for t in results["tests"]}
    assert shown == {f"C{n}": "hidden" for n in range(1, 9)}
    assert results["visibility"] == "hidden"


def test_gradescope_visibility_outside_gradescopes_words_is_refused():
    from rubric import gradescope_results
    from rubric.scoring import GradeReport

    report = GradeReport(lesson="L03", student="a", rubric_version="1", rubric_hash="0" * 64, engine_version="1",
                         total=0, max_total=0, complete=True, items=[], config_findings=[])
    with pytest.raises(ValueError, match="after_published"):
        gradescope_results(report, 1.0, {"C1": "later"})


def test_each_submission_says_its_raw_penalty_counted_score_and_whether_it_counts(api):
    aid = create(api, due_at=at(hours=-2), hard_close_at=at(1), late_penalty_per_day=0.25, counted_attempt="best"
                 ).json()["id"]
    first = submit(api, aid).json()
    worse = checkpoint_sheet()
    worse["answers"]["C2"]["reason"] = "it_is_valid"
    second = submit(api, aid, sheet=worse).json()
    assert (first["raw_score"], first["penalty"], first["counted_score"], first["counts"]) == (8, 0.25, 6, True)
    assert (second["raw_score"], second["counted_score"], second["counts"]) == (7, 5.25, False)
    listed = {s["id"]: s["counts"] for s in api.client.get("/v1/submissions", headers=api.as_("alice")).json()}
    assert listed == {first["id"]: True, second["id"]: False}
    # The student's pages say the same: each attempt, which one counts, the lateness and the penalty taken.
    page = api.client.get("/submissions", headers=api.as_("alice")).text
    assert "Checkpoints, attempt 1 <span class=\"counts-badge\">counts</span>" in page
    assert "attempt 2 <span class=\"muted\">(another attempt counts)</span>" in page
    assert "2 h late (1 day charged) · late penalty −25%, counted 6<" in page
    report = api.client.get(f"/submissions/{second['id']}", headers=api.as_("alice")).text
    assert 'id="attempt">Assignment <span class="attempt">Checkpoints, attempt 2' in report and "counted 5.25" in report


def test_submissions_past_the_hourly_limit_get_429_with_retry_after_naming_the_rule(api):
    aid = create(api, max_per_hour=2).json()["id"]
    assert [submit(api, aid).status_code for _ in range(2)] == [202, 202]
    third = submit(api, aid)
    assert third.status_code == 429, third.text
    (err,) = third.json()["errors"]
    assert err["field"] == "assignment_id" and "allows 2 submissions per hour" in err["rule"]
    assert re.search(r"the next is allowed at 20\S+T\d\d:\d\d:\d\d\+00:00$", err["rule"]), err["rule"]
    assert 3500 <= int(third.headers["Retry-After"]) <= 3601  # to the named time, rounded up to the second
    assert submit(api, aid, who="bob").status_code == 202  # counted per student
    from tests.grader.services.setup.test_assignments import stored

    assert stored() == (3, 3 * 7)  # each graded on the 7 lesson cases, reused


def test_the_hourly_limit_is_checked_against_the_last_60_minutes(api):
    from datetime import timedelta

    from grader.core.db import new_session
    from grader.core.models import Submission

    aid = create(api, max_per_hour=1).json()["id"]
    sid = submit(api, aid).json()["id"]
    with new_session() as session:  # that submission was made 61 minutes ago
        row = session.get(Submission, sid)
        row.created_at -= timedelta(minutes=61)
        session.commit()
    assert submit(api, aid).status_code == 202
    assert submit(api, aid).status_code == 429


def test_lateness_reads_in_days_hours_and_minutes_with_the_days_charged():
    from grader.services.setup.assignments import late_text

    assert [late_text(s) for s in (0, 59, 7200, 27914, 86400, 93780)] == [
        "on time", "59 s late (1 day charged)", "2 h late (1 day charged)", "7 h 45 min late (1 day charged)",
        "1 d late (1 day charged)", "1 d 2 h 3 min late (2 days charged)"]


def test_the_gradescope_export_hides_what_waits_for_a_students_extension(api):
    """Issue 44, hostile pass 12 (medium): Gradescope's after_due_date opens at its assignment's due date, not at a
    student's extension; alice, extended past the close, would have read her after_due items there while the site
    still withheld them. While the extension runs they are hidden; bob's file keeps the gate."""
    aid = create(api, visibility="after_due", open_at=at(-3), due_at=at(-2), hard_close_at=at(-1)).json()["id"]
    granted = api.client.post(f"/v1/assignments/{aid}/extensions", headers=api.as_("prof"),
                              json={"student": "alice", "due_at": at(1), "hard_close_at": at(2)})
    assert granted.status_code == 201, granted.text
    sid = submit(api, aid).json()["id"]
    mine = api.client.get(f"/v1/submissions/{sid}/grade", headers=api.as_("alice"))
    assert mine.status_code == 409 and "shown after the due date" in mine.json()["detail"]  # until her own due date
    results = api.client.get(f"/v1/submissions/{sid}/gradescope.json", headers=api.as_("prof")).json()
    shown = {t["name"].split(":")[0]: t["visibility"] for t in results["tests"]}
    assert set(shown.values()) == {"hidden"}, shown
