"""Variant pools on the in-process app (SQLite, enqueueing recorded): generating one (roles, determinism, refusals),
screening a broken variant before anything runs, assigning students evenly, and a submission to an assignment with a
pool running its student's own cases. The measured path (real worker, real Genesis) is
tests/integration/test_variants.py."""

from __future__ import annotations

import copy
import re
from collections import Counter
from datetime import timedelta

import pytest
from sqlalchemy import select

import rubric
from rubric.scoring import lesson_run_specs
from tests.grader.services.setup.test_assignments import at, create
from tests.factories import reference_sheet


def pool_assignment(api, **over) -> int:
    """An assignment of course l03 that opens in an hour: a pool may still be generated for it."""
    response = create(api, part="sheet", title="Own lab", open_at=at(hours=1), **over)
    assert response.status_code == 201, response.text
    return response.json()["id"]


def generate(api, assignment_id: int, who="prof", **body):
    return api.client.post(f"/v1/assignments/{assignment_id}/variants", json={"seed": 7, **body},
                           headers=api.as_(who))


def test_an_instructor_generates_a_deterministic_pool_and_each_variants_lesson_runs_are_queued(api):
    assignment_id = pool_assignment(api)
    for who, code in (("alice", 403), ("tess", 403), ("eve", 404)):
        assert generate(api, assignment_id, who=who, k=4).status_code == code, who
    response = generate(api, assignment_id, k=4)
    assert response.status_code == 201, response.text
    pool = response.json()
    drawn = rubric.draw_pool(rubric.load_variant_space("L03"), seed=7, k=4)
    assert [(v["id"], v["parameters"]) for v in pool["variants"]] == [(v.id, v.parameters) for v in drawn.variants]
    assert pool["state"] == "measuring" and {v["state"] for v in pool["variants"]} == {"measuring"}
    # every variant's seven lesson runs and its exercise and extension configs, as the variant's specs
    assert len(api.sent) == 4 * 9

    from grader.core.db import new_session
    from grader.core.models import PoolVariant, Submission

    with new_session() as session:
        for row in session.scalars(select(PoolVariant)):
            measuring = session.get(Submission, row.submission_id)
            assert measuring.variant_id == row.id
            variant = rubric.Variant(id=row.name, parameters=row.parameters)
            lesson = {spec.name: spec.model_dump(mode="json", exclude_computed_fields=True)
                      for spec in lesson_run_specs(variant)}
            assert {run.name: run.spec for run in measuring.case_runs if run.name in lesson} == lesson

    listed = api.client.get(f"/v1/assignments/{assignment_id}/variants", headers=api.as_("tess"))
    assert listed.status_code == 200 and listed.json()["variants"] == pool["variants"]
    assert api.client.get(f"/v1/assignments/{assignment_id}/variants", headers=api.as_("alice")).status_code == 403
    assert api.client.get(f"/v1/assignments/{assignment_id}/copy-flags", headers=api.as_("alice")).status_code == 403
    assert api.client.get(f"/v1/assignments/{assignment_id}/copy-flags", headers=api.as_("prof")).json() == []


def test_a_pool_is_refused_once_the_assignment_opened_a_second_time_or_past_k(api):
    opened = create(api, part="sheet", open_at=at(hours=-1)).json()["id"]
    response = generate(api, opened)
    assert response.status_code == 409 and response.json()["errors"][0]["field"] == "assignment", response.text
    assert "before the assignment opens" in response.json()["errors"][0]["rule"]
    assert api.client.get(f"/v1/assignments/{opened}/variants", headers=api.as_("prof")).json() is None
    later = pool_assignment(api)
    response = generate(api, later, k=65)
    assert response.status_code == 422 and "k" in response.text
    assert generate(api, later, k=2).status_code == 201
    again = generate(api, later, k=2, seed=8)
    assert again.status_code == 409 and "has a pool already" in again.json()["errors"][0]["rule"]
    assert api.client.get(f"/v1/assignments/{later}/variants", headers=api.as_("prof")).json()["seed"] == 7


def _services_pool(api, k: int = 4):
    """A pool generated through the service (not measured yet): (assignment id, pool id)."""
    from grader.core.db import new_session
    from grader.core.models import Assignment, User
    from grader.services.setup import variants

    assignment_id = pool_assignment(api)
    with new_session() as session:
        prof = session.scalar(select(User).where(User.name == "prof"))
        pool = variants.generate(session=session, assignment=session.get(Assignment, assignment_id), user=prof,
                                 seed=7, k=k)
        return assignment_id, pool.id


class Recorded:
    def __init__(self):
        self.runs, self.grades = [], []

    def send_case_run(self, case_run_id, delivery, backend, *, priority=0):
        self.runs.append(case_run_id)

    def send_grade(self, submission_id):
        self.grades.append(submission_id)

    def queue_listeners(self, backend):
        return ["cpu@test"]


def test_a_variant_whose_parameters_break_a_constraint_is_dropped_with_the_reason_and_nothing_of_it_runs(api):
    from grader.core.db import new_session
    from grader.core.models import PoolVariant, User, VariantPool
    from grader.services.setup import variants

    assignment_id, pool_id = _services_pool(api)
    with new_session() as session:
        broken = session.scalars(select(PoolVariant).where(PoolVariant.pool_id == pool_id)
                                 .order_by(PoolVariant.position)).all()[1]
        # the low lane above the table: B1 would have no answer (constraint lanes_straddle_table)
        broken.parameters = {**broken.parameters, "low_lane_friction": 0.7}
        session.commit()
        sender = Recorded()
        prof = session.scalar(select(User).where(User.name == "prof"))
        measuring = variants.measure(session=session, pool=session.get(VariantPool, pool_id), user=prof,
                                     sender=sender)
        assert len(measuring) == 3 and len(sender.runs) == 3 * 9
        session.refresh(broken)
        assert broken.state == "dropped" and broken.submission_id is None
        assert "lanes_straddle_table" in broken.reason and "refused before measuring" in broken.reason
    rows = api.client.get(f"/v1/assignments/{assignment_id}/variants", headers=api.as_("tess")).json()
    assert [(v["state"], v["reason"] is not None) for v in rows["variants"]] == [
        ("measuring", False), ("dropped", True), ("measuring", False), ("measuring", False)]
    assert (rows["kept"], rows["dropped"], rows["state"]) == (0, 1, "measuring")


def _all_kept_but(pool_id: int, dropped: str) -> None:
    """Decide every variant of the pool as its lab check would: kept, but `dropped` (the pool is then ready)."""
    from grader.core.db import new_session
    from grader.core.models import PoolVariant
    from grader.core.variants import decide

    with new_session() as session:
        for row in session.scalars(select(PoolVariant).where(PoolVariant.pool_id == pool_id)):
            row.state = "measuring"
            decide(session, row, kept=row.name != dropped, reason=None if row.name != dropped else "lab check failed")
        session.commit()


def test_students_get_kept_variants_evenly_each_fixed_at_the_first_visit(api):
    from grader.core.db import new_session
    from grader.core.models import Assignment, User
    from grader.services.errors import Conflict
    from grader.services.setup import student_variants

    assignment_id, pool_id = _services_pool(api, k=4)
    with new_session() as session:
        assignment = session.get(Assignment, assignment_id)
        alice = session.scalar(select(User).where(User.name == "alice"))
        with pytest.raises(Conflict, match="still being measured"):
            student_variants.variant_for(session=session, assignment=assignment, student=alice)
    _all_kept_but(pool_id, "v7-2")
    with new_session() as session:
        assignment = session.get(Assignment, assignment_id)
        course_id = assignment.course_id
        students = [User(course_id=course_id, name=f"s{i}", role="student") for i in range(9)]
        session.add_all(students)
        session.flush()
        given = {s.name: student_variants.variant_for(session=session, assignment=assignment, student=s).name
                 for s in students}
        session.commit()
        assert Counter(given.values()) == {"v7-1": 3, "v7-3": 3, "v7-4": 3}
        again = {s.name: student_variants.variant_for(session=session, assignment=assignment, student=s).name
                 for s in students}
        assert again == given
        assert student_variants.student_variant(session=session, assignment=assignment,
                                                student=students[0]).id == given["s0"]


def test_a_submission_to_a_pool_assignment_runs_and_records_its_students_variant_a_free_one_none(api):
    from grader.core.db import new_session
    from grader.core.models import Assignment, StudentVariant, Submission

    assignment_id, pool_id = _services_pool(api, k=2)
    _all_kept_but(pool_id, "none")
    with new_session() as session:
        assignment = session.get(Assignment, assignment_id)
        assignment.open_at -= timedelta(hours=2)  # it opened after its pool was measured
        session.commit()
    sheet = reference_sheet()
    response = api.client.post("/v1/submissions", json={"sheet": sheet, "assignment_id": assignment_id},
                               headers=api.as_("alice"))
    assert response.status_code == 202, response.text
    free = api.client.post("/v1/submissions", json={"sheet": sheet}, headers=api.as_("alice"))
    assert free.status_code == 202, free.text
    with new_session() as session:
        own = session.get(Submission, response.json()["id"])
        fixed = session.scalar(select(StudentVariant).where(StudentVariant.assignment_id == assignment_id))
        assert own.variant_id == fixed.variant_id and own.variant.name in ("v7-1", "v7-2")
        alice_id = own.student_id
        variant = rubric.Variant(id=own.variant.name, parameters=own.variant.parameters)
        specs = rubric.cases_to_run(rubric.parse_sheet(sheet), rubric.load_rubric("L03"), variant)
        assert {run.name: run.spec for run in own.case_runs} == {
            s.name: s.model_dump(mode="json", exclude_computed_fields=True) for s in specs}
        n1 = next(run for run in own.case_runs if run.name == "N1")
        assert n1.spec["dt"] == variant.parameters["fine_dt"] and n1.spec["duration"] == variant.parameters["duration"]
        shipped = session.get(Submission, free.json()["id"])
        assert shipped.variant_id is None
    # An instructor's sheet to the same assignment is on the lesson's shipped cases, as the instructor's form shows,
    # and takes no variant from the pool (a student's share of it is counted by StudentVariant rows).
    staff = api.client.post("/v1/submissions", json={"sheet": sheet, "assignment_id": assignment_id},
                            headers=api.as_("prof"))
    assert staff.status_code == 202, staff.text
    with new_session() as session:
        assert session.get(Submission, staff.json()["id"]).variant_id is None
        assert session.scalars(select(StudentVariant.student_id).where(
            StudentVariant.assignment_id == assignment_id)).all() == [alice_id]
    with new_session() as session:
        shipped = session.get(Submission, free.json()["id"])
        assert {run.name: run.spec for run in shipped.case_runs} == {
            s.name: s.model_dump(mode="json", exclude_computed_fields=True)
            for s in rubric.cases_to_run(rubric.parse_sheet(sheet), rubric.load_rubric("L03"))}


def test_grader_grade_reads_a_variant_by_pool_id_or_by_its_parameters():
    import click

    from grader.cli.grade import load_variant

    drawn = rubric.draw_pool(rubric.load_variant_space("L03"), seed=7, k=3).variants[2]
    assert load_variant("v7-3", "L03", None) == drawn
    by_json = load_variant('{"id": "v7-3", "parameters": %s}' % __import__("json").dumps(drawn.parameters), "L03", None)
    assert by_json.parameters == drawn.parameters and by_json.id == "v7-3"
    partial = load_variant('{"table_friction": 0.45}', "L03", None)
    assert partial.parameters["table_friction"] == 0.45 and partial.parameters["fine_dt"] == 0.01
    with pytest.raises(click.BadParameter, match="drop_height"):
        load_variant('{"parameters": {"drop_height": 1}}', "L03", None)


def test_a_pool_with_variants_dropped_is_drawn_further_from_its_seed_until_k_may_be_kept(api):
    from grader.core.db import new_session
    from grader.core.models import Assignment, PoolVariant, User
    from grader.services.errors import Conflict
    from grader.services.setup import variants

    assignment_id, pool_id = _services_pool(api, k=2)
    with new_session() as session:
        prof = session.scalar(select(User).where(User.name == "prof"))
        with pytest.raises(Conflict, match="not drawn further"):  # still measuring (drawn, never decided)
            variants.top_up(session=session, assignment=session.get(Assignment, assignment_id), user=prof,
                            sender=Recorded())
    _all_kept_but(pool_id, "v7-1")
    assert api.client.post(f"/v1/assignments/{assignment_id}/variants/top-up",
                           headers=api.as_("tess")).status_code == 403
    response = api.client.post(f"/v1/assignments/{assignment_id}/variants/top-up", headers=api.as_("prof"))
    assert response.status_code == 200, response.text
    pool = response.json()
    third = rubric.draw_pool(rubric.load_variant_space("L03"), seed=7, k=3).variants[2]
    assert [(v["id"], v["state"]) for v in pool["variants"]] == [
        ("v7-1", "dropped"), ("v7-2", "kept"), ("v7-3", "measuring")]
    assert pool["variants"][2]["parameters"] == third.parameters and pool["state"] == "measuring"
    assert len(api.sent) == 9  # the new variant's runs only
    with new_session() as session:
        new = session.scalar(select(PoolVariant).where(PoolVariant.name == "v7-3"))
        assert new.submission_id is not None and new.position == 3
    again = api.client.post(f"/v1/assignments/{assignment_id}/variants/top-up", headers=api.as_("prof"))
    assert again.status_code == 409 and "still being measured" in again.text


def test_counted_grades_name_each_students_variant_in_the_api_and_the_csv(api):
    """The counted grades of an assignment on variants say which lab each counted attempt was graded on (a last
    `variant` column in the CSV); an assignment without a pool keeps the columns it had."""
    import csv
    import io

    from grader.core.db import new_session
    from grader.core.models import Assignment, Grade, Submission

    assignment_id, pool_id = _services_pool(api, k=2)
    _all_kept_but(pool_id, "none")
    with new_session() as session:
        assignment = session.get(Assignment, assignment_id)
        assignment.open_at -= timedelta(hours=2)
        session.commit()
    posted = api.client.post("/v1/submissions", json={"sheet": reference_sheet(), "assignment_id": assignment_id},
                             headers=api.as_("alice"))
    assert posted.status_code == 202, posted.text
    with new_session() as session:  # graded as the worker would store it: the total is not the point here
        submission = session.get(Submission, posted.json()["id"])
        submission.status = "graded"
        session.add(Grade(submission_id=submission.id, rubric_lesson="L03", rubric_version="2", rubric_hash="h",
                          total=21, max_total=30, report={}))
        session.commit()
        variant = submission.variant.name
    rows = api.client.get(f"/v1/assignments/{assignment_id}/grades", headers=api.as_("prof")).json()
    assert [(r["student"], r["variant"]) for r in rows] == [("alice", variant)], rows
    exported = api.client.get(f"/v1/assignments/{assignment_id}/grades.csv", headers=api.as_("prof"))
    assert exported.status_code == 200, exported.text
    (row,) = csv.DictReader(io.StringIO(exported.text))
    assert (row["student"], row["counted_score"], row["variant"]) == ("alice", "21", variant)
    plain = create(api, title="No pool").json()["id"]
    header = api.client.get(f"/v1/assignments/{plain}/grades.csv", headers=api.as_("prof")).text.splitlines()[0]
    assert "variant" not in header, header


def test_no_student_gets_a_variant_while_the_pool_is_still_measuring_though_some_are_kept_already(api):
    """A pool hands out variants once every one is kept or dropped: a student drawn earlier would be spread over the
    variants kept so far, not over the pool."""
    from grader.core.db import new_session
    from grader.core.models import Assignment, PoolVariant, StudentVariant, Submission
    from grader.core.variants import decide

    assignment_id, pool_id = _services_pool(api, k=2)
    with new_session() as session:
        first, second = session.scalars(select(PoolVariant).where(PoolVariant.pool_id == pool_id)
                                        .order_by(PoolVariant.position)).all()
        first.state = second.state = "measuring"
        decide(session, first, kept=True, reason=None)  # the second's lab check has not landed
        session.get(Assignment, assignment_id).open_at -= timedelta(hours=2)
        session.commit()
        assert first.pool.state == "measuring"
    posted = api.client.post("/v1/submissions", json={"sheet": reference_sheet(), "assignment_id": assignment_id},
                             headers=api.as_("alice"))
    assert posted.status_code == 409, posted.text
    (error,) = posted.json()["errors"]
    assert error["field"] == "assignment_id" and "still being measured" in error["rule"], error
    with new_session() as session:
        assert session.scalars(select(StudentVariant)).all() == []
        assert session.scalars(select(Submission).where(Submission.assignment_id == assignment_id)).all() == []
        second = session.get(PoolVariant, second.id)
        decide(session, second, kept=True, reason=None)
        session.commit()
    assert api.client.post("/v1/submissions", json={"sheet": reference_sheet(), "assignment_id": assignment_id},
                           headers=api.as_("alice")).status_code == 202


def test_kept_variants_no_measured_item_tells_apart_are_named_on_the_pool_page_and_in_its_json(api):
    """Issue 47: copy evidence counts only items whose expected answers differ between two variants; a pair that
    expects alike on every measured item cannot show copying, and the instructor is told so. The measuring grades are
    stored here as the worker would store them (the reference sheet's report, each item credited and given the
    variant's expected answer): the first variant expects another A2 than the other two, which expect alike."""
    from grader.core.db import new_session
    from grader.core.models import Grade, PoolVariant, User, VariantPool, utcnow
    from grader.services.setup import variants
    from tests.factories import reference_sheet

    assignment_id, pool_id = _services_pool(api, k=3)
    with new_session() as session:
        prof = session.scalar(select(User).where(User.name == "prof"))
        variants.measure(session=session, pool=session.get(VariantPool, pool_id), user=prof, sender=Recorded())
    _all_kept_but(pool_id, "none")
    book = rubric.load_rubric("L03")
    base = rubric.grade_sheet(rubric.parse_sheet(reference_sheet()), {}, book).model_dump(mode="json")
    with new_session() as session:
        rows = session.scalars(select(PoolVariant).where(PoolVariant.pool_id == pool_id)
                               .order_by(PoolVariant.position)).all()
        names = [row.name for row in rows]
        for n, row in enumerate(rows):
            report = copy.deepcopy(base) | {"variant": row.name}
            for item in report["items"]:
                item["verdict"], item["expected"] = "credit", "alike"
                if item["id"] == "A2" and n == 0:
                    item["expected"] = "the first variant's own"
            session.add(Grade(submission_id=row.submission_id, rubric_lesson="L03", rubric_version=str(book.version),
                              rubric_hash=book.content_hash, total=report["total"], max_total=report["max_total"],
                              report=report, completed_at=utcnow()))
        session.commit()

    pool = api.client.get(f"/v1/assignments/{assignment_id}/variants", headers=api.as_("prof"))
    assert pool.status_code == 200, pool.text
    assert pool.json()["indistinct"] == [[names[1], names[2]]], pool.json()["indistinct"]
    page = api.client.get(f"/assignments/{assignment_id}", headers=api.as_("prof"))
    assert page.status_code == 200
    assert f'id="indistinct-{names[1]}-{names[2]}"' in page.text and "No measured item tells" in page.text
    assert f"indistinct-{names[0]}" not in page.text


def test_a_student_never_reads_a_variant_id_which_names_the_pool_seed(api):
    """Issue 47: a variant's id (v7-1) shows its pool's seed, and with the space public every other variant could be
    drawn offline from it. A student reads their lab as its parameters only: no page, API answer or event of theirs
    names the id or the seed, before or after they submit and are graded."""
    from grader.core.db import new_session
    from grader.core.grading import grade_and_store
    from grader.core.models import Assignment, Submission

    assignment_id, pool_id = _services_pool(api, k=2)
    _all_kept_but(pool_id, "none")
    with new_session() as session:
        session.get(Assignment, assignment_id).open_at -= timedelta(hours=2)
        session.commit()
    as_alice = api.as_("alice")
    read = ["/courses/l03", f"/assignments/{assignment_id}/sheet", f"/v1/assignments/{assignment_id}/sheet",
            "/v1/sheets"]
    bodies = {url: api.client.get(url, headers=as_alice) for url in read}
    made = api.client.post("/v1/submissions", json={"sheet": reference_sheet(), "assignment_id": assignment_id},
                           headers=as_alice)
    assert made.status_code == 202, made.text
    sid = made.json()["id"]
    with new_session() as session:  # graded on no run (every measured item not measured): the report names its variant
        submission = session.get(Submission, sid)
        variant = submission.variant.name
        grade_and_store(session=session, submission=submission, book=rubric.load_rubric("L03"), complete=True)
        session.commit()
        assert session.get(Submission, sid).status == "graded"
    for url in (f"/v1/submissions/{sid}", f"/v1/submissions/{sid}/grade", f"/v1/submissions/{sid}/grades",
                f"/v1/submissions/{sid}/case-runs", f"/v1/submissions/{sid}/events", "/v1/submissions",
                f"/submissions/{sid}", f"/submissions/{sid}/progress", "/courses/l03"):
        bodies[f"{url} (after)"] = api.client.get(url, headers=as_alice)
    assert all(r.status_code == 200 for r in bodies.values()), {u: r.status_code for u, r in bodies.items()}
    assert variant.startswith("v7-")
    named = re.compile(rf"{re.escape(variant)}|\bv7-[0-9]")  # this variant's id, or any id of the pool's seed
    leaks = {url: [r.text[max(0, m.start() - 120):m.end() + 60] for m in named.finditer(r.text)][:2]
             for url, r in bodies.items() if named.search(r.text)}
    assert not leaks, leaks
