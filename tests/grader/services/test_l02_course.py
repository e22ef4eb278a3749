"""L02 in a course, in-process (issue 45, item 5): an L02 assignment graded through the worker's own path on real
Genesis runs (`l02_measured`, the case process replaced by those recorded results), then what a course does with a
grade, for L02 as for L03 and with nothing outside lessons/l02 naming it: an instructor's override, a student's
review request answered with one, a rubric version published and a regrade under it (the override kept), the
student's course page, the counted grades, the course CSV and Gradescope. The real app on SQLite."""

from __future__ import annotations

import copy
import csv
import dataclasses
import io
import shutil
from pathlib import Path

import pytest
import yaml

from grader.core import clock
from rubric import load_rubric
from tests.grader.services.setup.test_assignments import at

EXAMPLES = Path(__file__).resolve().parents[3] / "examples"
pytestmark = pytest.mark.slow
COMMENT = "P1 asks for the height at 0.3 s; the sheet's reason names the wrong run. Half a point."


def _graded_l02(api, l02_measured) -> tuple[int, int]:
    """(an L02 assignment's id, alice's submission to it): its three runs done by the worker's own code on the
    recorded real results, graded and its lab check stored."""
    from grader.core.db import new_session
    from worker.case_run import process_case_run
    from worker.grading import complete_grade, grade_submission

    made = api.client.post("/v1/courses/l03/assignments", headers=api.as_("prof"), json={
        "title": "The lifecycle lab", "lesson": "L02", "part": "sheet", "open_at": at(days=-1), "due_at": at(days=7),
        "hard_close_at": at(days=8)})
    assert made.status_code == 201, made.text
    aid = made.json()["id"]
    sheet = yaml.safe_load((EXAMPLES / "l02" / "reference.yaml").read_text())
    submitted = api.client.post("/v1/submissions", json={"sheet": sheet, "assignment_id": aid},
                                headers=api.as_("alice"))
    assert submitted.status_code == 202, submitted.text
    sid = submitted.json()["id"]

    def run_case(spec, out_dir: Path, **_):
        result = l02_measured[spec.name]
        shutil.copytree(result.out_dir, out_dir, dirs_exist_ok=True)
        return dataclasses.replace(result, spec=spec, out_dir=str(out_dir))

    assert len(api.sent) == 3
    for case_run_id, delivery, _backend in api.sent:
        with new_session() as session:
            process_case_run(session=session, case_run_id=case_run_id, delivery=delivery, run_case=run_case)
    with new_session() as session:
        grade_submission(session=session, submission_id=sid)
        complete_grade(session=session, submission_id=sid)
    return aid, sid


def _grade(api, sid, who="alice") -> dict:
    response = api.client.get(f"/v1/submissions/{sid}/grade", headers=api.as_(who))
    assert response.status_code == 200, response.text
    return response.json()


def test_an_l02_grade_is_overridden_reviewed_regraded_and_exported_like_any_other(api, l02_measured):
    aid, sid = _graded_l02(api, l02_measured)
    grade = _grade(api, sid)
    assert (grade["rubric_lesson"], grade["total"], grade["max_total"]) == ("L02", 22, 22), grade
    assert grade["check"]["verdict_line"] == "L02 CHECK: PASSED"
    points = {i["id"]: i["points"] for i in grade["items"]}

    # An instructor's override of P1, and a review request on P2 answered with another.
    made = api.client.post(f"/v1/submissions/{sid}/overrides", headers=api.as_("prof"),
                           json={"item_id": "P1", "score": points["P1"] - 0.5, "comment": COMMENT})
    assert made.status_code == 201, made.text
    asked = api.client.post(f"/v1/submissions/{sid}/review-requests", headers=api.as_("alice"),
                            json={"item_id": "P2", "message": "My P2 reason was cut off; may I add it?"})
    assert asked.status_code == 201, asked.text
    answered = api.client.post(f"/v1/review-requests/{asked.json()['id']}/answer", headers=api.as_("prof"),
                               json={"answer": "The answer stands; the reason is not graded. No change.",
                                     "score": points["P2"]})
    assert answered.status_code == 200 and answered.json()["override_id"], answered.text
    grade = _grade(api, sid)
    items = {i["id"]: i for i in grade["items"]}
    assert grade["total"] == 21.5 and items["P1"]["override"]["comment"] == COMMENT, grade["total"]
    assert (items["P1"]["score"], items["P1"]["measured_score"]) == (points["P1"] - 0.5, points["P1"])

    # L02 v2 published with P3 worth one point more, and the course regraded under it: the overrides stay in force.
    content = copy.deepcopy(load_rubric("L02", "1").model_dump(mode="json"))
    content["version"] = "2"
    content["review"] = {"reviewer": "L02 course test instructor", "review_date": clock.now().date().isoformat(),
                         "notes": "P3 weighs one point more"}
    content["items"] = [i | {"points": i["points"] + 1} if i["id"] == "P3" else i for i in content["items"]]
    published = api.client.post("/v1/rubrics/versions", json=content, headers=api.as_("prof"))
    assert published.status_code == 201, published.text
    preview = api.client.get("/v1/courses/l03/regrade-preview?version=2&lesson=L02", headers=api.as_("prof"))
    assert preview.status_code == 200, preview.text
    assert [e["submission_id"] for e in preview.json()["entries"]] == [sid], preview.json()
    committed = api.client.post("/v1/courses/l03/regrades", headers=api.as_("prof"), json={
        "lesson": "L02", "version": "2", "content_hash": preview.json()["content_hash"]})
    assert committed.status_code == 201, committed.text
    grade = _grade(api, sid)
    items = {i["id"]: i for i in grade["items"]}
    assert (grade["rubric_lesson"], grade["rubric_version"], grade["max_total"]) == ("L02", "2", 23), grade
    assert grade["total"] == 22.5 and items["P3"]["points"] == points["P3"] + 1
    assert items["P1"]["override"]["comment"] == COMMENT and grade["check"]["verdict_line"] == "L02 CHECK: PASSED"

    # What the course reads: the counted grade, the CSVs, Gradescope, the student's course page.
    counted = api.client.get(f"/v1/assignments/{aid}/grades", headers=api.as_("prof")).json()
    assert [(c["student"], c["counted_score"], c["max_score"]) for c in counted] == [("alice", 22.5, 23)], counted
    rows = list(csv.DictReader(io.StringIO(api.client.get("/v1/courses/l03/grades.csv",
                                                          headers=api.as_("prof")).text)))
    (row,) = [r for r in rows if r["submission_id"] == str(sid)]
    # one lesson graded in the course: its items' plain ids, as an L03-only course's file has always had
    assert "lesson" not in row and (row["total"], row["P1"], row["P3"]) == ("22.5", "2.5", "4"), row
    exported = api.client.get(f"/v1/submissions/{sid}/gradescope.json", headers=api.as_("prof")).json()
    assert exported["score"] == 22.5 and {t["name"].split(":")[0] for t in exported["tests"]} >= {"P1", "P3"}
    page = api.client.get("/courses/l03", headers=api.as_("alice"))
    assert page.status_code == 200 and "The lifecycle lab" in page.text and "22.5" in page.text
