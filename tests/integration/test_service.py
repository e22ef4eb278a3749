"""The deployed topology as processes: API over HTTP, a real Celery worker on Redis, PostgreSQL, real Genesis."""

from __future__ import annotations

import csv
import io
from importlib.metadata import version

import httpx
import numpy as np
import pytest
from sqlalchemy import select
from sqlalchemy.orm import Session

from grader.core.models import Measurement
from grader.core import content_key as reuse
from rubric import case_metrics, cases_to_run, expected_arrays, load_rubric, parse_case, parse_sheet
from rubric.metrics import parse_metrics
from tests.integration.helpers import case_runs, events, grades_of, submit_and_wait
from tests.factories import reference_sheet

pytestmark = [pytest.mark.integration, pytest.mark.slow]


@pytest.fixture(scope="module")
def first(stack):
    """The reference sheet, graded once; the later tests build on it."""
    created, final = submit_and_wait(stack, reference_sheet())
    return created, final


def test_reference_sheet_gets_full_marks_from_cpu_measurements_of_exactly_its_cases(stack, first):
    created, final = first
    assert final["status"] == "graded", final
    specs = {spec.name: spec for spec in cases_to_run(parse_sheet(reference_sheet()))}
    assert final["progress"]["done"] == final["progress"]["total"] == len(specs)
    client = stack.client()
    # The reference answers earn every item of the current rubric, at that item's points.
    grade = client.grade(created["id"])
    rubric = load_rubric("L03")
    assert (grade["rubric_version"], grade["rubric_hash"]) == (rubric.version, rubric.content_hash)
    assert [i["id"] for i in grade["items"]] == [item.id for item in rubric.items]
    for stored, item in zip(grade["items"], rubric.items):
        assert (stored["verdict"], stored["score"], stored["max_score"]) == ("credit", item.points, item.points), stored
    assert grade["total"] == grade["max_total"] == sum(item.points for item in rubric.items)
    runs = client.case_runs(created["id"])
    assert sorted(run["name"] for run in runs) == sorted(specs)
    for run in runs:
        assert run["status"] == "done" and run["result_status"] == "ok", run
        assert parse_case(run["spec"]) == specs[run["name"]]  # what ran is what the sheet asked for
        prov = run["provenance"]
        assert prov["requested_backend"] == prov["actual_backend"] == run["actual_backend"] == run["backend"] == "cpu"
        assert prov["case"] == run["name"] and prov["versions"]["genesis"] == version("genesis-world")
        inputs = reuse.key_inputs(run["spec"], backend=run["backend"], precision=run["precision"])
        assert run["content_key"] == reuse.content_key(inputs)
        # The downloadable arrays are what the spec promises, and the stored metrics were computed from them.
        response = httpx.get(f"{stack.url}/v1/submissions/{created['id']}/case-runs/{run['name']}/files/arrays.npz",
                             headers={"Authorization": f"Bearer {stack.tokens['alice']}"})
        assert response.status_code == 200
        with np.load(io.BytesIO(response.content), allow_pickle=False) as npz:
            arrays = {name: npz[name] for name in npz.files}
        spec = parse_case(run["spec"])
        assert set(arrays) == set(expected_arrays(spec))
        assert parse_metrics(run["metrics"]) == case_metrics(spec, arrays), run["name"]
    assert grades_of(stack, created["id"]) == 1


def test_same_configs_again_reuse_the_measurements_and_say_so(stack, first):
    created, _ = first
    again, final = submit_and_wait(stack, reference_sheet(), who="bob")
    assert final["status"] == "graded"
    # Every case found its stored measurement when submitted: nothing was queued, only the grade task was sent.
    assert again["status"] in ("grading", "graded") and again["progress"]["done"] == again["progress"]["total"] == 9
    assert sum("found when submitted" in (e.detail or "") for e in events(stack, again["id"])) == 9
    assert not any(e.state == "running" for e in events(stack, again["id"]))
    before = {run.name: run for run in case_runs(stack, created["id"])}
    for run in case_runs(stack, again["id"]):
        first_run = before[run.name]  # itself a reuse when an earlier test measured the same spec
        assert run.reused_from_id == (first_run.reused_from_id or first_run.id), run.name
        assert run.measurement_id == first_run.measurement_id is not None
        assert run.content_key == before[run.name].content_key
        assert run.provenance == before[run.name].provenance
    assert any("reused measurement" in (e.detail or "") for e in events(stack, again["id"]))
    assert stack.client("bob").grade(again["id"])["total"] == stack.client().grade(created["id"])["total"]


@pytest.fixture(scope="module")
def misconceived(stack, first):
    """A second graded submission that loses A4 (same measurements, reused), so exports must carry real scores."""
    sheet = reference_sheet()
    sheet["answers"]["A4"]["same_length"] = True  # "equal substep_dt means equal array length"
    created, final = submit_and_wait(stack, sheet)
    assert final["status"] == "graded", final
    a4 = next(i for i in stack.client("prof").grade(created["id"])["items"] if i["id"] == "A4")
    assert (a4["verdict"], a4["score"]) == ("no_credit", 0), a4
    return created


def test_course_csv_matches_every_stored_grade(stack, first, misconceived):
    prof = stack.client("prof")
    headers = {"Authorization": f"Bearer {stack.tokens['prof']}"}
    listed = httpx.get(f"{stack.url}/v1/courses/l03-test/submissions", headers=headers).json()
    graded = sorted((s for s in listed if s["status"] == "graded"), key=lambda s: s["id"])
    assert {first[0]["id"], misconceived["id"]} <= {s["id"] for s in graded}
    response = httpx.get(f"{stack.url}/v1/courses/l03-test/grades.csv", headers=headers)
    assert response.status_code == 200
    rows = list(csv.DictReader(io.StringIO(response.text)))
    assert len(rows) == len(graded)  # one row per graded submission, in submission order
    for row, submission in zip(rows, graded):
        grade = prof.grade(submission["id"])
        assert (row["student"], row["rubric_version"]) == (submission["student"], grade["rubric_version"])
        assert (float(row["total"]), float(row["max_total"])) == (grade["total"], grade["max_total"])
        scores = {i["id"]: None if i["verdict"] == "inconclusive" else i["score"] for i in grade["items"]}
        assert {i: float(row[i]) if row[i] else None for i in scores} == scores, submission["id"]


def test_gradescope_results_match_the_stored_grade(stack, first, misconceived):
    prof = {"Authorization": f"Bearer {stack.tokens['prof']}"}
    for submission_id in (first[0]["id"], misconceived["id"]):
        grade = stack.client("prof").grade(submission_id)
        results = httpx.get(f"{stack.url}/v1/submissions/{submission_id}/gradescope.json", headers=prof).json()
        assert results["score"] == grade["total"]
        assert f"{grade['total']:g} / {grade['max_total']:g}" in results["output"]
        assert f"rubric version {grade['rubric_version']} " in results["output"]
        assert [(t["name"].split(":")[0], t["score"], t["max_score"], t["output"]) for t in results["tests"]] == [
            (i["id"], i["score"], i["max_score"], i["feedback"]) for i in grade["items"]]


def test_course_views_and_exports_respect_roles(stack, first):
    created, _ = first
    prof = {"Authorization": f"Bearer {stack.tokens['prof']}"}
    listed = httpx.get(f"{stack.url}/v1/courses/l03-test/submissions", headers=prof).json()
    assert created["id"] in [s["id"] for s in listed]
    student = {"Authorization": f"Bearer {stack.tokens['alice']}"}
    assert httpx.get(f"{stack.url}/v1/courses/l03-test/grades.csv", headers=student).status_code == 403
    assert httpx.get(f"{stack.url}/v1/submissions/{created['id']}/gradescope.json",
                     headers=student).status_code == 403
    # The figures' data, read from the database under the service's run names: the student's own table exercise
    # beside the baseline, each lane's series (the browser draws them; no worker draws a PNG any more).
    series = httpx.get(f"{stack.url}/submissions/{created['id']}/series.json", headers=student, timeout=120)
    assert series.status_code == 200, series.text
    runs = {r["name"]: r for r in series.json()["runs"]}
    for name in ("friction-baseline", "sheet.table_exercise"):
        assert [lane["name"] for lane in runs[name]["lanes"]] == ["low", "high"], name
        assert all(len(lane["x"]) == len(runs[name]["series"]["t"]) > 0 for lane in runs[name]["lanes"]), name
    assert httpx.get(f"{stack.url}/v1/submissions/{created['id']}/series", headers=student).json() == series.json()


def test_a_checkpoint_assignment_is_graded_by_the_worker_on_the_lesson_cases_then_at_once_on_them(stack):
    """Forced to measure anew, the first checkpoint sheet queues the lesson's cases, the worker runs them and grades
    it; the next one is graded in its request on exactly those runs, reused, nothing queued."""
    from datetime import UTC, timedelta

    from rubric.scoring import LESSON_RUNS
    from tests.grader.services.setup.test_assignments import checkpoint_sheet

    from grader.core import clock

    now = clock.now().replace(tzinfo=UTC)  # the service's clock: CLOCK_SHIFT_DAYS moves both
    aid = stack.client("prof").create_assignment("l03-test", {
        "title": "Checkpoints", "part": "checkpoints", "open_at": (now - timedelta(hours=1)).isoformat(),
        "due_at": (now + timedelta(days=1)).isoformat(), "hard_close_at": (now + timedelta(days=2)).isoformat()})["id"]
    # forcing a re-measurement is a staff power: the course's instructor sends the first sheet
    created, final = submit_and_wait(stack, checkpoint_sheet("prof"), "prof", assignment_id=aid, force_rerun=True)
    assert created["status"] != "graded" and created["progress"]["total"] == len(LESSON_RUNS)
    assert (final["status"], final["total"], final["max_total"]) == ("graded", 8, 8), final
    measured = {run.name: run for run in case_runs(stack, created["id"])}
    assert sorted(measured) == sorted(LESSON_RUNS)
    assert all(r.status == "done" and r.reused_from_id is None and r.actual_backend == "cpu" for r in measured.values())
    again = stack.client("bob").submit(checkpoint_sheet("bob"), assignment_id=aid)
    assert (again["status"], again["total"]) == ("graded", 8)
    # each reuses the measurement stored under the content key the forced run computed (the first one measured of
    # that key: a forced run keeps its own evidence and does not replace it)
    with Session(stack.engine) as session:
        stored = dict(session.execute(select(Measurement.content_key, Measurement.case_run_id)).all())
    reused = {r.name: (r.content_key, r.reused_from_id) for r in case_runs(stack, again["id"])}
    assert reused == {n: (r.content_key, stored[r.content_key]) for n, r in measured.items()}
    assert grades_of(stack, again["id"]) == 1
