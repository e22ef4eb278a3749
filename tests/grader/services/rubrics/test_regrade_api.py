"""Rubric versions and regrades over the real app in-process: who may publish, preview and commit, and what
governance and validation refuse. The regrade of real graded runs is tests/integration/test_regrade.py."""

from __future__ import annotations

from tests.factories import rubric_v3


def test_shipped_versions_are_listed_as_rows_for_staff_only(api):
    listed = api.client.get("/v1/rubrics/L03/versions", headers=api.as_("prof"))
    assert listed.status_code == 200, listed.text
    versions = {v["version"]: v for v in listed.json()}
    assert set(versions) == {"1", "2"} and {v["source"] for v in versions.values()} == {"shipped"}
    assert versions["2"]["published_by"] is None and versions["2"]["review"]["reviewer"]
    assert api.client.get("/v1/rubrics/L03/versions", headers=api.as_("tess")).status_code == 200
    assert api.client.get("/v1/rubrics/L03/versions", headers=api.as_("alice")).status_code == 403
    assert api.client.get("/v1/rubrics/L3/versions", headers=api.as_("prof")).status_code == 422


def test_an_instructor_publishes_a_version_and_it_is_recorded_with_who_and_when(api):
    published = api.client.post("/v1/rubrics/versions", json=rubric_v3(high_lane_unchanged=0.001),
                                headers=api.as_("prof"))
    assert published.status_code == 201, published.text
    body = published.json()
    assert (body["version"], body["source"], body["published_by"]) == ("3", "published", "prof")
    assert body["published_at"]
    again = api.client.post("/v1/rubrics/versions", json=rubric_v3(high_lane_unchanged=0.001), headers=api.as_("prof"))
    assert again.status_code == 201 and again.json()["content_hash"] == body["content_hash"]  # idempotent
    listed = api.client.get("/v1/rubrics/L03/versions", headers=api.as_("prof")).json()
    assert [v["version"] for v in listed] == ["1", "2", "3"]


def test_only_instructors_publish(api):
    for who in ("alice", "tess"):
        response = api.client.post("/v1/rubrics/versions", json=rubric_v3(), headers=api.as_(who))
        assert response.status_code == 403 and "only instructors" in response.json()["detail"], who


def test_governance_refuses_an_unreviewed_tolerance_change_and_a_changed_shipped_version(api):
    unreviewed = rubric_v3()
    unreviewed["tolerances"]["high_lane_unchanged"]["value"] = 0.5  # same reviewer and date as v2's record
    response = api.client.post("/v1/rubrics/versions", json=unreviewed, headers=api.as_("prof"))
    assert response.status_code == 409
    assert "tolerances.high_lane_unchanged" in response.json()["detail"] and "without a new review" in response.json()["detail"]
    same_review = rubric_v3() | {"review": rubric_v3()["review"] | {"reviewer": "rubric v2 author"}}
    same_review["review"] = api.client.get("/v1/rubrics/L03/versions", headers=api.as_("prof")).json()[1]["review"]
    response = api.client.post("/v1/rubrics/versions", json=same_review, headers=api.as_("prof"))
    assert response.status_code == 409 and "repeats the review record" in response.json()["detail"]


def test_a_malformed_rubric_names_the_field_and_the_rule(api):
    bad = rubric_v3()
    bad["tolerances"]["high_lane_unchanged"]["value"] = -1
    bad["items"][0]["points"] = "many"
    response = api.client.post("/v1/rubrics/versions", json=bad, headers=api.as_("prof"))
    assert response.status_code == 422
    fields = {e["field"] for e in response.json()["errors"]}
    assert "tolerances.high_lane_unchanged.value" in fields and "items.0.points" in fields, response.json()
    unknown = rubric_v3() | {"grading_mode": "lenient"}
    response = api.client.post("/v1/rubrics/versions", json=unknown, headers=api.as_("prof"))
    assert response.status_code == 422 and any(e["field"] == "grading_mode" for e in response.json()["errors"])
    listed = api.client.get("/v1/rubrics/L03/versions", headers=api.as_("prof")).json()
    assert [v["version"] for v in listed] == ["1", "2"]  # nothing half-stored


def test_regrade_access_rules(api):
    api.client.post("/v1/rubrics/versions", json=rubric_v3(), headers=api.as_("prof"))
    preview = "/v1/courses/l03/regrade-preview?version=3"
    assert api.client.get(preview, headers=api.as_("prof")).status_code == 200
    assert api.client.get(preview, headers=api.as_("tess")).status_code == 200  # auditors read
    assert api.client.get(preview, headers=api.as_("alice")).status_code == 403
    assert api.client.get(preview, headers=api.as_("eve")).status_code == 404  # another course's instructor
    assert api.client.get("/v1/courses/l03/regrade-preview?version=9", headers=api.as_("prof")).status_code == 404
    archived = api.client.get("/v1/courses/l03/regrade-preview?version=1", headers=api.as_("prof"))
    assert archived.status_code == 409 and "archived" in archived.json()["detail"]
    previewed = api.client.get(preview, headers=api.as_("prof")).json()["content_hash"]
    commit = {"lesson": "L03", "version": "3", "content_hash": previewed}
    assert api.client.post("/v1/courses/l03/regrades", json=commit, headers=api.as_("tess")).status_code == 403
    assert api.client.post("/v1/courses/l03/regrades", json=commit, headers=api.as_("alice")).status_code == 403
    bad = api.client.post("/v1/courses/l03/regrades", json=commit | {"force": True}, headers=api.as_("prof"))
    assert bad.status_code == 422 and any(e["field"].endswith("force") for e in bad.json()["errors"])
    assert api.client.get("/v1/courses/l03/regrades", headers=api.as_("prof")).json() == []


def test_committing_with_no_graded_submission_records_the_course_version(api):
    published = api.client.post("/v1/rubrics/versions", json=rubric_v3(), headers=api.as_("prof")).json()
    commit = {"version": "3", "content_hash": published["content_hash"]}
    response = api.client.post("/v1/courses/l03/regrades", json=commit, headers=api.as_("prof"))
    assert response.status_code == 201, response.text
    body = response.json()
    assert (body["version"], body["committed_by"], body["regraded"], body["changed"]) == ("3", "prof", 0, 0)
    history = api.client.get("/v1/courses/l03/regrades", headers=api.as_("tess")).json()
    assert [r["id"] for r in history] == [body["id"]]
    from grader.core.db import new_session
    from grader.core.rubrics import course_version
    from grader.core.models import Course

    with new_session() as session:
        course = session.query(Course).filter_by(name="l03").one()
        assert course_version(session, course.id, "L03") == "3"
        other = session.query(Course).filter_by(name="other").one()
        assert course_version(session, other.id, "L03") == "2"


def test_the_cases_a_submission_runs_follow_the_courses_rubric_version(api):
    """The rubric that decides which configs run is the one that grades them: a course on a version whose extension
    may also change the duration runs a sheet's extension with a changed duration (the shipped version would void
    it as a one-factor violation and run nothing for it, then grade it under a rule that allows it)."""
    from tests.factories import reference_sheet

    v3 = rubric_v3()
    v3["configs"]["extension"]["may_change"] = ["dt", "substeps", "duration"]
    published = api.client.post("/v1/rubrics/versions", json=v3, headers=api.as_("prof"))
    assert published.status_code == 201, published.text
    commit = {"version": "3", "content_hash": published.json()["content_hash"]}
    assert api.client.post("/v1/courses/l03/regrades", json=commit, headers=api.as_("prof")).status_code == 201
    sheet = reference_sheet()
    sheet["configs"]["extension"]["duration"] = 2.0
    submitted = api.client.post("/v1/submissions", json={"sheet": sheet}, headers=api.as_("alice"))
    assert submitted.status_code == 202, submitted.text
    runs = api.client.get(f"/v1/submissions/{submitted.json()['id']}/case-runs", headers=api.as_("alice")).json()
    extension = [r for r in runs if r["name"].endswith("extension")]
    assert len(extension) == 1, [r["name"] for r in runs]
    assert extension[0]["spec"]["duration"] == 2.0
