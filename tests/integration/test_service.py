"""The deployed topology as processes: API over HTTP, a real Celery worker on Redis, PostgreSQL, real Genesis."""

from __future__ import annotations

import io

import httpx
import numpy as np
import pytest

from rubric import expected_arrays, parse_case
from tests.integration.helpers import case_runs, events, grades_of, submit_and_wait
from tests.factories import reference_sheet

pytestmark = [pytest.mark.integration, pytest.mark.slow]


@pytest.fixture(scope="module")
def first(stack):
    """The reference sheet, graded once; the later tests build on it."""
    created, final = submit_and_wait(stack, reference_sheet())
    return created, final


def test_reference_sheet_is_graded_with_provenance_for_every_case_run(stack, first):
    created, final = first
    assert final["status"] == "graded", final
    assert final["progress"]["done"] == final["progress"]["total"] > 0
    client = stack.client()
    grade = client.grade(created["id"])
    assert grade["items"] and grade["max_total"] > 0
    for item in grade["items"]:
        assert {"id", "question", "score", "max_score", "verdict", "feedback"} <= set(item)
        assert 0 <= item["score"] <= item["max_score"]
    assert grade["total"] == pytest.approx(sum(i["score"] for i in grade["items"]))
    runs = client.case_runs(created["id"])
    for run in runs:
        assert run["status"] == "done" and run["result_status"] == "ok", run
        prov = run["provenance"]
        assert prov["requested_backend"] == prov["actual_backend"] == run["actual_backend"] == run["backend"] == "cpu"
        assert prov["case"] == run["name"] and prov["versions"]["genesis"]
        assert len(run["content_key"]) == 64
    # The measured arrays are downloadable and are what the spec promises.
    run = runs[0]
    response = httpx.get(f"{stack.url}/v1/submissions/{created['id']}/case-runs/{run['name']}/files/arrays.npz",
                         headers={"Authorization": f"Bearer {stack.tokens['alice']}"})
    assert response.status_code == 200
    with np.load(io.BytesIO(response.content), allow_pickle=False) as npz:
        assert set(npz.files) == set(expected_arrays(parse_case(run["spec"])))
    assert grades_of(stack, created["id"]) == 1


def test_same_configs_again_reuse_the_measurements_and_say_so(stack, first):
    created, _ = first
    again, final = submit_and_wait(stack, reference_sheet(), who="bob")
    assert final["status"] == "graded"
    before = {run.name: run for run in case_runs(stack, created["id"])}
    for run in case_runs(stack, again["id"]):
        first_run = before[run.name]  # itself a reuse when an earlier test measured the same spec
        assert run.reused_from_id == (first_run.reused_from_id or first_run.id), run.name
        assert run.measurement_id == first_run.measurement_id is not None
        assert run.content_key == before[run.name].content_key
        assert run.provenance == before[run.name].provenance
    assert any("reused measurement" in (e.detail or "") for e in events(stack, again["id"]))
    assert stack.client("bob").grade(again["id"])["total"] == stack.client().grade(created["id"])["total"]


def test_instructor_sees_the_course_and_exports_grades(stack, first):
    created, _ = first
    prof = {"Authorization": f"Bearer {stack.tokens['prof']}"}
    listed = httpx.get(f"{stack.url}/v1/courses/l03-test/submissions", headers=prof).json()
    assert created["id"] in [s["id"] for s in listed]
    csv = httpx.get(f"{stack.url}/v1/courses/l03-test/grades.csv", headers=prof)
    assert csv.status_code == 200 and "alice" in csv.text
    results = httpx.get(f"{stack.url}/v1/submissions/{created['id']}/gradescope.json", headers=prof).json()
    assert results["tests"]
    student = {"Authorization": f"Bearer {stack.tokens['alice']}"}
    assert httpx.get(f"{stack.url}/v1/courses/l03-test/grades.csv", headers=student).status_code == 403
    figures = httpx.get(f"{stack.url}/v1/submissions/{created['id']}/figures", headers=student, timeout=120)
    assert figures.status_code == 200 and figures.json()
    png = httpx.get(f"{stack.url}/v1/submissions/{created['id']}/figures/{figures.json()[0]}", headers=student)
    assert png.status_code == 200 and png.content[:4] == b"\x89PNG"
