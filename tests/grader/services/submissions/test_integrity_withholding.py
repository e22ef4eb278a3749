"""Withholding that cannot be side-stepped (issue 26): a free submission (no assignment) shows a student nothing an
assignment of their course still withholds, events carry no scores, the lab check waits with the withheld items, and a
course may take students' submissions only to an assignment. On the in-process app (SQLite)."""

from __future__ import annotations

import re

from sqlalchemy import select, update

from tests.factories import reference_sheet
from tests.grader.services.setup.test_assignments import at, create, stored, submit
from tests.grader.services.setup.test_assignments import lesson_cases_stored  # noqa: F401 - autouse: the lesson measured
from tests.grader.core.test_grade_then_complete import _submission_ready_to_grade

SCORE = re.compile(r"\d(\.\d+)? / \d")  # "7 / 8", "grade 6.5 / 8": a total in an event's detail


def free_submit(api, who="alice"):
    """The whole sheet sent with no assignment_id."""
    return api.client.post("/v1/submissions", json={"sheet": reference_sheet() | {"student": who}},
                           headers=api.as_(who))


def free_graded(api, measured, *, complete: bool = False, sheet: dict | None = None) -> int:
    """Alice's free submission of the whole sheet (the reference one, or `sheet`), graded by the worker's own task on
    the session's real measurements (and its figures and lab check drawn with `complete`)."""
    from grader.core.db import new_session
    from worker.grading import complete_grade, grade_submission

    sid = _submission_ready_to_grade(api, measured, sheet)
    with new_session() as session:
        assert grade_submission(session=session, submission_id=sid) is not None
        if complete:
            assert complete_grade(session=session, submission_id=sid) is not None
    return sid


def grade_of(api, sid, who):
    return api.client.get(f"/v1/submissions/{sid}/grade", headers=api.as_(who))


def event_details(api, sid, who="alice") -> list[str]:
    events = api.client.get(f"/v1/submissions/{sid}/events", headers=api.as_(who))
    assert events.status_code == 200, events.text
    return [e["detail"] or "" for e in events.json()]


def test_a_free_submission_withholds_the_items_an_assignment_withholds_until_release(api, measured):
    aid = create(api, visibility="on_release").json()["id"]  # assignment 1 withholds C1-C8 until released
    sid = free_graded(api, measured)
    staff = grade_of(api, sid, "prof").json()  # staff see every item at once
    assert "pending" not in {i["verdict"] for i in staff["items"]}
    by_id = {i["id"]: i for i in staff["items"]}
    withheld = [f"C{n}" for n in range(1, 9)]
    grade = grade_of(api, sid, "alice")
    assert grade.status_code == 200, grade.text
    items = {i["id"]: i for i in grade.json()["items"]}
    for i in withheld:
        assert (items[i]["score"], items[i]["verdict"], items[i]["expected"], items[i]["evidence"]) == (
            None, "pending", "", None), items[i]
        assert re.search(r"withheld: shown once “[^”]+” is released by an instructor", items[i]["feedback"])
    # What no assignment withholds is shown, unless its verdict would tell a withheld item's answer: A1 reads N4,
    # whose kind of run C1 reads (issue 44, hostile pass 6), so it waits with C1, saying so; an item reading no run
    # (conceptual, config) is shown whole.
    a1 = items["A1"]
    assert (a1["score"], a1["verdict"], a1["evidence"]) == (None, "pending", None), a1
    assert "its verdict reads the measurements that decide C" in a1["feedback"], a1
    shown = [i for i, item in items.items() if item["verdict"] != "pending"]
    # (a conceptual item's runs only illustrate it: its verdict stays, their numbers wait with them)
    assert shown and all((items[i]["score"], items[i]["verdict"]) == (by_id[i]["score"], by_id[i]["verdict"])
                         and by_id[i]["kind"] in ("conceptual", "config") for i in shown), shown
    pending_points = sum(by_id[i]["points"] for i in items if i not in shown)
    shown_total = sum(by_id[i]["score"] for i in shown)
    assert grade.json()["total"] == round(shown_total, 6) and grade.json()["pending"].startswith(
        f"{pending_points:g} of ")
    row = api.client.get(f"/v1/submissions/{sid}", headers=api.as_("alice")).json()
    assert row["total"] == grade.json()["total"] and "C1, C2" in row["pending"]
    assert api.client.get(f"/v1/submissions/{sid}/grades", headers=api.as_("alice")).status_code == 409
    results = api.client.get(f"/submissions/{sid}/results.json", headers=api.as_("alice")).json()
    assert {i["id"]: i["verdict"] for i in results["items"]}["C5"] == "pending"
    page = api.client.get(f"/submissions/{sid}", headers=api.as_("alice")).text
    assert f"{pending_points:g} of " in page and by_id["C5"]["feedback"] not in page
    assert "part pending" in api.client.get("/submissions", headers=api.as_("alice")).text
    # Released: the same stored grade, every item shown.
    assert api.client.post(f"/v1/assignments/{aid}/release", headers=api.as_("prof")).status_code == 200
    after = grade_of(api, sid, "alice").json()
    assert after["items"] == staff["items"] and after["total"] == staff["total"] and after["pending"] is None


def test_a_free_submission_is_withheld_but_for_its_config_item_while_a_sheet_assignment_withholds_every_item(api, measured):
    """Everything is withheld but H5, the config item: decided from the student's own configs, which the form's Check
    tells before submitting, it is always shown (issue 44, hostile pass 7)."""
    create(api, part="sheet", visibility="after_due")
    sid = free_graded(api, measured)
    grade = grade_of(api, sid, "alice")
    assert grade.status_code == 200, grade.text
    items = {i["id"]: i for i in grade.json()["items"]}
    assert [i for i, item in items.items() if item["verdict"] != "pending"] == ["H5"], items
    staff = {i["id"]: i for i in grade_of(api, sid, "prof").json()["items"]}
    assert items["H5"] == staff["H5"] and grade.json()["total"] == staff["H5"]["score"]
    assert "shown after the due date" in grade.json()["pending"]
    row = api.client.get(f"/v1/submissions/{sid}", headers=api.as_("alice")).json()
    assert row["total"] == staff["H5"]["score"]
    assert grade_of(api, sid, "prof").status_code == 200


def test_an_assignment_submission_withholds_what_another_assignment_of_the_lesson_withholds(api, measured):
    """Issue 44 (hostile pass 2): an exam withholds C1-C8 until released; a practice assignment of the same
    checkpoints shows them at once. Alice's practice attempt answered 200 with every verdict and the conceptual items'
    expected answers: the exam's, a click away. Now it withholds them as the exam does, until the exam is released."""
    exam = create(api, title="Exam", visibility="on_release").json()["id"]
    practice = create(api, title="Practice").json()["id"]  # immediate
    sid = submit(api, practice).json()["id"]
    assert submit(api, exam).status_code == 202
    grade = grade_of(api, sid, "alice")
    assert grade.status_code == 409 and "once “Exam” is released" in grade.json()["detail"], grade.text
    text = api.client.get(f"/submissions/{sid}", headers=api.as_("alice")).text
    assert "unequal_simulated_duration" not in text and 'id="total"' not in text
    staff = grade_of(api, sid, "prof").json()
    assert staff["items"][0]["verdict"] != "pending"
    assert api.client.post(f"/v1/assignments/{exam}/release", headers=api.as_("prof")).status_code == 200
    shown = grade_of(api, sid, "alice")
    assert shown.status_code == 200 and shown.json()["items"] == staff["items"]


def test_only_assignments_of_the_students_own_course_that_still_withhold_count(api, measured):
    # Another course's assignment withholds nothing here; one whose due date has passed shows its items.
    assert create(api, who="eve", course="other", visibility="on_release").status_code == 201
    assert create(api, visibility="after_due", open_at=at(-3), due_at=at(-2), hard_close_at=at(1)).status_code == 201
    sid = free_graded(api, measured)
    grade = grade_of(api, sid, "alice")
    assert grade.status_code == 200 and grade.json()["pending"] is None
    assert "pending" not in {i["verdict"] for i in grade.json()["items"]}
    # An assignment not open yet withholds its items already: a free submission must not answer it in advance.
    assert create(api, visibility="after_due", open_at=at(1), due_at=at(2), hard_close_at=at(3)).status_code == 201
    later = grade_of(api, sid, "alice").json()
    assert "C1, C2, C3, C4, C5, C6, C7, C8" in later["pending"] and all(
        i["verdict"] == "pending" for i in later["items"] if i["id"].startswith("C")), later["pending"]


def test_events_carry_no_scores_graded_by_the_worker_at_once_or_resent(api, measured):
    from grader.core.db import new_session
    from grader.core.grades import grade_history
    from grader.core.models import CaseRun

    aid = create(api, visibility="on_release").json()["id"]
    at_once = submit(api, aid).json()["id"]  # a checkpoint sheet, graded in the request
    details = event_details(api, at_once)
    assert not any(SCORE.search(d) for d in details), details  # was "8 / 8 (no case run: graded at once ...)"
    assert any("graded at once" in d for d in details), details
    sid = free_graded(api, measured, complete=True)
    details += event_details(api, sid)
    assert not any(SCORE.search(d) or "CHECK:" in d for d in details), details
    assert any("graded under rubric L03 v" in d for d in details), details
    assert any(d.startswith("lab check stored") for d in details), details
    with new_session() as session:  # one of its runs failed since: an instructor re-sends it
        run_id = session.scalar(select(CaseRun.id).where(CaseRun.submission_id == sid).limit(1))
        session.execute(update(CaseRun).where(CaseRun.id == run_id).values(status="failed", error="boom"))
        session.commit()
    assert api.client.post(f"/v1/case-runs/{run_id}/resend", headers=api.as_("prof")).status_code == 202
    details = event_details(api, sid)
    assert not any(SCORE.search(d) for d in details), details  # was "grade 30 / 30 (v2) kept in the history"
    assert any("kept in the history, superseded" in d for d in details), details
    with new_session() as session:
        assert len(grade_history(session, sid)) == 1  # the grade is kept, only the event says less


def test_the_lab_check_waits_while_any_item_is_withheld(api, measured):
    aid = create(api, item_visibility={"C3": "on_release"}).json()["id"]
    sid = free_graded(api, measured, complete=True)
    check = api.client.get(f"/submissions/{sid}/results.json", headers=api.as_("prof")).json()["check"]
    evidence = check["conditions"][0]["evidence"]
    staff = api.client.get(f"/submissions/{sid}", headers=api.as_("prof")).text
    assert check["verdict_line"] in staff and 'id="lab-check"' in staff
    student = api.client.get(f"/submissions/{sid}", headers=api.as_("alice")).text
    assert "L03 CHECK: " not in student and 'id="lab-check"' not in student and evidence not in student
    assert "lab check is shown once every item" in student
    assert api.client.get(f"/submissions/{sid}/results.json", headers=api.as_("alice")).json()["check"] is None
    assert api.client.post(f"/v1/assignments/{aid}/release", headers=api.as_("prof")).status_code == 200
    assert check["verdict_line"] in api.client.get(f"/submissions/{sid}", headers=api.as_("alice")).text


def test_a_course_may_take_students_submissions_only_to_an_assignment(api):
    assert api.client.get("/v1/courses/l03", headers=api.as_("alice")).json()["free_submissions"] is True
    before = stored()
    for who, body, code, field in (("alice", {"free_submissions": False}, 403, None),
                                   ("eve", {"free_submissions": False}, 404, None),
                                   ("prof", {"free_submissions": "sometimes"}, 422, "free_submissions"),
                                   ("prof", {}, 422, "body")):
        response = api.client.patch("/v1/courses/l03", json=body, headers=api.as_(who))
        assert response.status_code == code, (body, response.text)
        if field is not None:
            assert field in {e["field"] for e in response.json()["errors"]}, response.json()
    assert api.client.get("/v1/courses/l03", headers=api.as_("prof")).json()["free_submissions"] is True
    off = api.client.patch("/v1/courses/l03", json={"free_submissions": False}, headers=api.as_("prof"))
    assert off.status_code == 200 and off.json()["free_submissions"] is False, off.text
    assert off.json()["timezone"] == "UTC"  # one setting changed, the other kept
    refused = free_submit(api)
    assert refused.status_code == 409, refused.text
    (err,) = refused.json()["errors"]
    assert err["field"] == "assignment_id" and "only to an assignment" in err["rule"], err
    assert stored() == before  # nothing stored
    assert free_submit(api, who="prof").status_code == 202  # staff may always submit freely
    aid = create(api).json()["id"]
    assert submit(api, aid).status_code == 202
    assert api.client.get("/v1/courses/other", headers=api.as_("eve")).json()["free_submissions"] is True


def test_the_cli_reads_and_sets_free_submissions(api, monkeypatch):
    from click.testing import CliRunner

    from grader.cli import course, main
    from tests.grader.cli.test_assignment_cli import client_on

    monkeypatch.setattr(course, "_client", client_on)
    done = CliRunner().invoke(main, ["course", "free-submissions", "l03", "off", "--token", api.tokens["prof"]])
    assert done.exit_code == 0, done.output
    assert "course l03: students submit only to an assignment" in done.output
    shown = CliRunner().invoke(main, ["course", "free-submissions", "l03", "--token", api.tokens["alice"]])
    assert shown.exit_code == 0 and "students submit only to an assignment" in shown.output, shown.output
    on = CliRunner().invoke(main, ["course", "free-submissions", "l03", "on", "--token", api.tokens["prof"]])
    assert "course l03: students may also submit outside assignments" in on.output, on.output
    bad = CliRunner().invoke(main, ["course", "free-submissions", "l03", "maybe", "--token", api.tokens["prof"]])
    assert bad.exit_code != 0 and "maybe" in bad.output
    refused = CliRunner().invoke(main, ["course", "free-submissions", "l03", "off", "--token", api.tokens["alice"]])
    assert refused.exit_code != 0
