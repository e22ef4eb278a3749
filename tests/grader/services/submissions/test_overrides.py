"""Manual overrides over the real app in-process (SQLite): one item's score set with a required comment, used by every
reader (the API, the counted score, the CSVs, Gradescope, the dashboard, the report page), never leaking a withheld
item, kept in the history and through a regrade. Grades are real: checkpoint sheets graded on the lesson's cases as
really measured (the session's Genesis runs)."""

from __future__ import annotations

import csv
import io

import pytest

from tests.factories import rubric_v3
from tests.grader.services.setup.test_assignments import create, submit
from tests.grader.services.setup.test_assignments import lesson_cases_stored  # noqa: F401 - autouse: the lesson measured

COMMENT = "Your reason for C2 quotes the wrong condition; the answer alone does not earn the point."


def graded(api, **assignment) -> tuple[int, int]:
    """(assignment id, alice's graded checkpoint submission id)."""
    aid = create(api, **assignment).json()["id"]
    response = submit(api, aid)
    assert response.status_code == 202 and response.json()["status"] == "graded", response.text
    return aid, response.json()["id"]


def override(api, sid, who="prof", **body):
    payload = {"item_id": "C2", "score": 0, "comment": COMMENT} | body
    return api.client.post(f"/v1/submissions/{sid}/overrides", json=payload, headers=api.as_(who))


def items(api, sid, who="alice") -> dict[str, dict]:
    grade = api.client.get(f"/v1/submissions/{sid}/grade", headers=api.as_(who))
    assert grade.status_code == 200, grade.text
    return {i["id"]: i for i in grade.json()["items"]}


def test_an_override_reaches_every_reader_with_the_measured_verdict_beside_it(api):
    aid, sid = graded(api)
    before = items(api, sid)
    assert before["C2"]["verdict"] == "credit" and before["C2"]["score"] == 1
    made = override(api, sid)
    assert made.status_code == 201, made.text
    body = made.json()
    assert (body["item_id"], body["score"], body["by"], body["comment"]) == ("C2", 0, "prof", COMMENT)
    assert (body["measured_score"], body["measured_verdict"], body["current"]) == (1, "credit", True)
    # The API grade: the override's score, the measured verdict and score kept, the comment and who.
    c2 = items(api, sid)["C2"]
    assert (c2["score"], c2["verdict"], c2["measured_score"]) == (0, "credit", 1)
    assert c2["override"]["comment"] == COMMENT and c2["override"]["by"] == "prof"
    grade = api.client.get(f"/v1/submissions/{sid}/grade", headers=api.as_("alice")).json()
    assert grade["total"] == 7 and grade["max_total"] == 8
    # The counted score, the assignment's CSV, the course CSV and Gradescope.
    row = api.client.get(f"/v1/submissions/{sid}", headers=api.as_("alice")).json()
    assert (row["raw_score"], row["counted_score"]) == (7, 7)
    counted = list(csv.DictReader(io.StringIO(api.client.get(f"/v1/assignments/{aid}/grades.csv",
                                                             headers=api.as_("prof")).text)))
    assert counted[0]["counted_score"] == "7"
    (course_row,) = csv.DictReader(io.StringIO(api.client.get("/v1/courses/l03/grades.csv",
                                                              headers=api.as_("prof")).text))
    assert (course_row["total"], course_row["C2"]) == ("7", "0")
    assert COMMENT in course_row["overrides"] and "measured: credit, 1" in course_row["overrides"]
    results = api.client.get(f"/v1/submissions/{sid}/gradescope.json", headers=api.as_("prof")).json()
    test = next(t for t in results["tests"] if t["name"].startswith("C2:"))
    assert results["score"] == 7 and test["score"] == 0 and COMMENT in test["output"]
    assert "measured: credit" in test["output"]
    # The dashboard: the override at its top, and the roster's total.
    dashboard = api.client.get("/v1/courses/l03/dashboard", headers=api.as_("prof")).json()
    assert [(o["item_id"], o["submission_id"]) for o in dashboard["recent_overrides"]] == [("C2", sid)]
    assert dashboard["roster"][0]["total"] == 7
    assert dashboard["assignments"][0]["grades"][0]["counted_score"] == 7
    # The history keeps the measured grade, superseded, and the overridden one, current.
    history = api.client.get(f"/v1/submissions/{sid}/grades", headers=api.as_("alice")).json()
    assert [(h["total"], h["current"]) for h in history] == [(8, False), (7, True)]
    # The report page, as the student: score, comment and the measured verdict.
    page = api.client.get(f"/submissions/{sid}", headers=api.as_("alice")).text
    assert COMMENT in page and 'id="override-C2"' in page and "score set by an instructor" in page
    assert "score of item C2 set by prof" in page  # the history says how the current grade came to be


@pytest.mark.parametrize("body, field, rule", [
    ({"score": 1.5}, "score", "from 0 to 1, item C2's points"),
    ({"score": -1}, "score", "from 0 to 1"),
    ({"comment": "   "}, "comment", "required"),
    ({"item_id": "H1"}, "item_id", "must be an item of this grade (C1, C2"),
])
def test_a_bad_override_names_the_field_and_the_rule_and_stores_nothing(api, body, field, rule):
    _, sid = graded(api)
    response = override(api, sid, **body)
    assert response.status_code == 422, response.text
    errors = {e["field"]: e["rule"] for e in response.json()["errors"]}
    assert field in errors and rule in errors[field], errors
    assert api.client.get(f"/v1/submissions/{sid}/overrides", headers=api.as_("prof")).json() == []
    assert len(api.client.get(f"/v1/submissions/{sid}/grades", headers=api.as_("prof")).json()) == 1


def test_an_unknown_field_or_a_non_number_is_refused_by_the_body_rules(api):
    _, sid = graded(api)
    assert override(api, sid, force=True).status_code == 422
    response = override(api, sid, score="lots")
    assert response.status_code == 422 and response.json()["errors"][0]["field"] == "score"


@pytest.mark.parametrize("who, status", [("alice", 403), ("tess", 403), ("bob", 404), ("eve", 404)])
def test_only_an_instructor_of_the_course_overrides(api, who, status):
    _, sid = graded(api)
    assert override(api, sid, who=who).status_code == status
    assert items(api, sid, "prof")["C2"]["score"] == 1


def test_a_withheld_items_override_stays_withheld_until_the_item_is_shown(api):
    aid, sid = graded(api, item_visibility={"C2": "on_release"})
    assert override(api, sid).status_code == 201
    grade = api.client.get(f"/v1/submissions/{sid}/grade", headers=api.as_("alice"))
    c2 = {i["id"]: i for i in grade.json()["items"]}["C2"]
    assert c2["score"] is None and c2["verdict"] == "pending" and "override" not in c2
    for leaked in (grade.text, api.client.get(f"/submissions/{sid}/results.json", headers=api.as_("alice")).text,
                   api.client.get(f"/submissions/{sid}", headers=api.as_("alice")).text,
                   api.client.get(f"/v1/submissions/{sid}", headers=api.as_("alice")).text):
        assert COMMENT not in leaked and "made_by_override" not in leaked and "measured_score" not in leaked
    assert grade.json()["total"] == 7 and grade.json()["pending"].startswith("1 of 8 points pending (C2)")
    assert api.client.get(f"/v1/submissions/{sid}/grades", headers=api.as_("alice")).status_code == 409
    # Released: the override is shown with its comment, and the measured verdict beside it.
    assert api.client.post(f"/v1/assignments/{aid}/release", headers=api.as_("prof")).status_code == 200
    c2 = items(api, sid)["C2"]
    assert (c2["score"], c2["verdict"], c2["override"]["comment"]) == (0, "credit", COMMENT)
    assert COMMENT in api.client.get(f"/submissions/{sid}", headers=api.as_("alice")).text


def test_a_second_override_supersedes_the_first_and_both_are_kept(api):
    _, sid = graded(api)
    first = override(api, sid).json()
    second = override(api, sid, score=0.5, comment="On a second look, half the reason holds.").json()
    listed = api.client.get(f"/v1/submissions/{sid}/overrides", headers=api.as_("prof")).json()
    assert [(o["id"], o["score"], o["current"]) for o in listed] == [(first["id"], 0, False),
                                                                    (second["id"], 0.5, True)]
    assert second["measured_score"] == 1 and second["measured_verdict"] == "credit"  # the measurement, not 0
    assert items(api, sid)["C2"]["score"] == 0.5 and items(api, sid)["C2"]["measured_score"] == 1
    totals = [g["total"] for g in api.client.get(f"/v1/submissions/{sid}/grades", headers=api.as_("prof")).json()]
    assert totals == [8, 7, 7.5]
    assert api.client.get(f"/v1/submissions/{sid}/overrides", headers=api.as_("alice")).status_code == 403


def test_a_regrade_under_a_new_version_keeps_the_override_and_its_preview_says_so(api):
    _, sid = graded(api)
    assert override(api, sid).status_code == 201
    published = api.client.post("/v1/rubrics/versions", json=rubric_v3(), headers=api.as_("prof"))
    assert published.status_code == 201, published.text
    preview = api.client.get("/v1/courses/l03/regrade-preview?version=3", headers=api.as_("prof")).json()
    (entry,) = [e for e in preview["entries"] if e["submission_id"] == sid]
    assert entry["skipped"] is None and entry["new_total"] == 7, entry
    assert entry["overrides"] == ["C2: override 0 of 1 by prof kept (the new version measures credit, 1)"]
    page = api.client.get("/courses/l03/regrade?version=3", headers=api.as_("prof")).text
    assert "C2: override 0 of 1 by prof kept" in page
    commit = api.client.post("/v1/courses/l03/regrades", json={"version": "3",
                                                                "content_hash": preview["content_hash"]},
                             headers=api.as_("prof"))
    assert commit.status_code == 201, commit.text
    grade = api.client.get(f"/v1/submissions/{sid}/grade", headers=api.as_("alice")).json()
    c2 = {i["id"]: i for i in grade["items"]}["C2"]
    assert grade["rubric_version"] == "3" and grade["total"] == 7
    assert (c2["score"], c2["measured_score"], c2["override"]["comment"]) == (0, 1, COMMENT)
    history = api.client.get(f"/v1/submissions/{sid}/grades", headers=api.as_("prof")).json()
    assert [(h["rubric_version"], h["total"]) for h in history] == [("2", 8), ("2", 7), ("3", 7)]


def test_a_run_of_an_overridden_submission_may_be_resent_and_grading_it_again_keeps_the_override(api):
    from grader.core.db import new_session
    from grader.core.grading import grade_and_store
    from grader.core.rubrics import course_rubric
    from grader.core.grades import current_grade
    from grader.core.models import CaseRun, Submission

    _, sid = graded(api)
    with new_session() as session:  # one of its runs failed (as a run can, after the grade was stored)
        run = session.query(CaseRun).filter_by(submission_id=sid, name="N4").one()
        run.status, run.error, run_id = "failed", "worker lost", run.id
        session.commit()
    assert override(api, sid).status_code == 201
    problem = next(p for p in api.client.get("/v1/courses/l03/dashboard", headers=api.as_("prof")).json()["problems"]
                   if p["case_run_id"] == run_id)
    assert problem["resendable"] is True, problem
    resent = api.client.post(f"/v1/case-runs/{run_id}/resend", headers=api.as_("prof"))
    assert resent.status_code == 202, resent.text
    with new_session() as session:  # what the worker does once the re-sent run is stored: grade the submission again
        submission = session.get(Submission, sid)
        assert current_grade(session, sid) is None  # the resend superseded the grade
        grade_and_store(session=session, submission=submission, complete=True,
                        book=course_rubric(session, submission.course_id, submission.lesson))
        session.commit()
    c2 = items(api, sid)["C2"]
    assert (c2["score"], c2["measured_score"], c2["override"]["comment"]) == (0, 1, COMMENT)  # the override stands
