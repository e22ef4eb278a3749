"""After a regrade, an override in force is listed beside the item as measured under the grade's current rubric version
(issue 31): `GET /v1/submissions/ID/overrides`, the dashboard's recent overrides and the report's override table
show the new version's measured verdict and score, not the one the override first replaced; a superseded override
keeps what its own grade measured. Real grades: a checkpoint sheet graded on the lesson's really measured cases."""

from __future__ import annotations

from tests.factories import rubric_v3
from tests.grader.services.setup.test_assignments import lesson_cases_stored  # noqa: F401 - autouse: the lesson measured
from tests.grader.services.submissions.test_overrides import graded, items, override


def _v3_with_c2_worth(points: float) -> dict:
    content = rubric_v3()
    content["items"] = [i | {"points": points} if i["id"] == "C2" else i for i in content["items"]]
    return content


def test_the_override_list_shows_the_measured_verdict_under_the_grades_current_version(api):
    _, sid = graded(api)
    first = override(api, sid, score=0.5, comment="Half of the reason holds.").json()
    made = override(api, sid).json()  # the one in force; the first is superseded and keeps its own measurement
    assert (made["measured_score"], made["measured_verdict"]) == (1, "credit"), made
    published = api.client.post("/v1/rubrics/versions", json=_v3_with_c2_worth(2.0), headers=api.as_("prof"))
    assert published.status_code == 201, published.text
    preview = api.client.get("/v1/courses/l03/regrade-preview?version=3", headers=api.as_("prof")).json()
    commit = api.client.post("/v1/courses/l03/regrades", headers=api.as_("prof"),
                             json={"version": "3", "content_hash": preview["content_hash"]})
    assert commit.status_code == 201, commit.text
    c2 = items(api, sid, "prof")["C2"]  # the current grade's item: the override kept, measured again under v3
    assert (c2["points"], c2["measured_score"], c2["score"]) == (2, 2, 0), c2

    listed = {o["id"]: o for o in api.client.get(f"/v1/submissions/{sid}/overrides", headers=api.as_("prof")).json()}
    now = listed[made["id"]]
    assert (now["measured_score"], now["measured_verdict"]) == (c2["measured_score"], c2["verdict"]), now
    recent = api.client.get("/v1/courses/l03/dashboard", headers=api.as_("prof")).json()["recent_overrides"]
    assert [(o["id"], o["measured_score"]) for o in recent] == [(made["id"], 2)], recent
    assert now["measured_rubric_version"] == "3" and made["measured_rubric_version"] == "2"
    old = listed[first["id"]]
    assert (old["current"], old["measured_score"], old["measured_rubric_version"]) == (False, 1, "2"), old
    page = api.client.get(f"/submissions/{sid}", headers=api.as_("prof")).text
    row = page.split('id="override-C2"')[1].split("</tr>")[0]
    assert "2 / 2" in row and "0 / 2" in row, row
