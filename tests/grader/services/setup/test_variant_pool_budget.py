"""Variant pools an instructor can rely on (issue 47), on the in-process app (SQLite, sending recorded): K means kept
(the pool draws further as variants are dropped, until K are kept or its draw budget is spent, and says which), a
top-up at any time (students keep their variant, new students get the new ones), no dead end for a pool that kept
none, and a minimum kept before students get one. Lab checks are decided here as the worker records them
(grader.core.variants.record_check's `decide`); the measured path is tests/integration/test_variant_pool_browser.py."""

from __future__ import annotations

from datetime import timedelta

import pytest
from sqlalchemy import select

import rubric
from tests.factories import reference_sheet
from tests.grader.services.setup.test_variants import generate, pool_assignment


def _decide(pool_id: int, verdicts: dict[str, bool]) -> list[int]:
    """Decide the named measuring variants (True: kept) and return their measuring submissions, as the worker's
    lab check would; the caller then lets the worker continue the pool for each (continue_pool)."""
    from grader.core.db import new_session
    from grader.core.models import PoolVariant
    from grader.core.variants import decide

    with new_session() as session:
        decided = []
        for row in session.scalars(select(PoolVariant).where(PoolVariant.pool_id == pool_id)):
            if row.name in verdicts:
                assert row.state == "measuring", (row.name, row.state)
                decide(session, row, kept=verdicts[row.name], reason=None if verdicts[row.name] else "lab check failed")
                decided.append(row.submission_id)
        session.commit()
        return decided


def _continue(submission_ids: list[int]) -> list:
    """What the worker does after each lab check (worker.tasks._continue_pool): the runs it would send."""
    from grader.core.db import new_session
    from grader.core.variants import continue_pool

    sent = []
    for submission_id in submission_ids:
        with new_session() as session:
            runs, grades = continue_pool(session, submission_id)
            sent += runs + grades
    return sent


def _open(assignment_id: int) -> None:
    from grader.core.db import new_session
    from grader.core.models import Assignment

    with new_session() as session:
        session.get(Assignment, assignment_id).open_at -= timedelta(hours=2)
        session.commit()


def _student_variant(assignment_id: int, name: str):
    """The variant a student of the course gets at their first visit (created if missing): its name."""
    from grader.core.db import new_session
    from grader.core.models import Assignment, User
    from grader.services.setup import student_variants

    with new_session() as session:
        assignment = session.get(Assignment, assignment_id)
        student = session.scalar(select(User).where(User.name == name))
        if student is None:
            student = User(course_id=assignment.course_id, name=name, role="student")
            session.add(student)
            session.flush()
        row = student_variants.variant_for(session=session, assignment=assignment, student=student)
        session.commit()
        return row.name


def test_k_means_kept_the_pool_draws_further_as_variants_drop_until_k_are_kept(api):
    assignment_id = pool_assignment(api)
    response = generate(api, assignment_id, k=3, budget=5)
    assert response.status_code == 201, response.text
    pool = response.json()
    assert (pool["k"], pool["draw_budget"], pool["drawn"]) == (3, 5, 3)
    assert pool["outcome"] == "measuring: 0 of 3 kept so far, 3 of at most 5 variants drawn"
    first_runs = len(api.sent)

    # v7-1 is dropped: the pool may no longer keep 3 with what it measures, so the seed's next draw is measured.
    sent = _continue(_decide(_pool_id(assignment_id), {"v7-1": False, "v7-2": True}))
    assert sent and len(sent) == first_runs // 3, sent  # one variant's runs, as each of the first
    listed = api.client.get(f"/v1/assignments/{assignment_id}/variants", headers=api.as_("prof")).json()
    fourth = rubric.draw_pool(rubric.load_variant_space("L03"), seed=7, k=4).variants[3]
    assert [(v["id"], v["state"]) for v in listed["variants"]] == [
        ("v7-1", "dropped"), ("v7-2", "kept"), ("v7-3", "measuring"), ("v7-4", "measuring")]
    assert listed["variants"][3]["parameters"] == fourth.parameters and listed["state"] == "measuring"

    # v7-3 and v7-4 kept: 3 kept of 3, nothing more is drawn, and the pool says so.
    assert _continue(_decide(_pool_id(assignment_id), {"v7-3": True, "v7-4": True})) == []
    listed = api.client.get(f"/v1/assignments/{assignment_id}/variants", headers=api.as_("prof")).json()
    assert (listed["state"], listed["kept"], listed["drawn"]) == ("ready", 3, 4)
    assert listed["outcome"] == "kept 3 of the 3 asked for, in 4 variants drawn"


def _pool_id(assignment_id: int) -> int:
    from grader.core.db import new_session
    from grader.core.models import VariantPool

    with new_session() as session:
        return session.scalar(select(VariantPool.id).where(VariantPool.assignment_id == assignment_id))


def test_a_pool_whose_budget_is_spent_says_so_and_its_students_are_told_the_lab_is_being_prepared(api):
    assignment_id = pool_assignment(api)
    assert generate(api, assignment_id, k=2, budget=3).status_code == 201
    pool_id = _pool_id(assignment_id)
    assert len(_continue(_decide(pool_id, {"v7-1": False, "v7-2": False}))) > 0  # one more: the budget's third
    assert _continue(_decide(pool_id, {"v7-3": False})) == []  # the budget is spent
    listed = api.client.get(f"/v1/assignments/{assignment_id}/variants", headers=api.as_("prof")).json()
    assert (listed["state"], listed["kept"], listed["drawn"], listed["serving"]) == ("ready", 0, 3, False)
    assert listed["outcome"] == ("the draw budget is spent: kept 0 of the 2 asked for after 3 variants drawn (at most "
                                 "3); top up to draw more")
    _open(assignment_id)
    posted = api.client.post("/v1/submissions", json={"sheet": reference_sheet(), "assignment_id": assignment_id},
                             headers=api.as_("alice"))
    assert posted.status_code == 409, posted.text
    rule = posted.json()["errors"][0]["rule"]
    assert "preparing more variants" in rule and "generate another" not in rule, rule
    # The next step exists: a top-up, after the assignment opened, draws the two it lacks.
    response = api.client.post(f"/v1/assignments/{assignment_id}/variants/top-up", headers=api.as_("prof"))
    assert response.status_code == 200, response.text
    assert [v["id"] for v in response.json()["variants"]][-2:] == ["v7-4", "v7-5"]
    _decide(pool_id, {"v7-4": True, "v7-5": True})
    assert _student_variant(assignment_id, "alice") in ("v7-4", "v7-5")


def test_a_live_pool_is_topped_up_students_keep_theirs_and_new_students_get_the_new_variants(api):
    assignment_id = pool_assignment(api)
    assert generate(api, assignment_id, k=2).status_code == 201
    pool_id = _pool_id(assignment_id)
    _decide(pool_id, {"v7-1": True, "v7-2": True})
    _open(assignment_id)
    first = {name: _student_variant(assignment_id, name) for name in ("alice", "s1")}
    assert sorted(first.values()) == ["v7-1", "v7-2"]

    before = len(api.sent)
    response = api.client.post(f"/v1/assignments/{assignment_id}/variants/top-up", json={"more": 2},
                               headers=api.as_("prof"))
    assert response.status_code == 200, response.text
    pool = response.json()
    assert (pool["k"], pool["state"], pool["drawn"]) == (4, "measuring", 4)
    assert len(api.sent) - before == 2 * before // 2  # the two new variants' runs, as many as the first two's
    # While the new ones are measured, students are still served (the pool's minimum became the 2 it served with).
    assert pool["minimum"] == 2 and pool["serving"] is True
    _decide(pool_id, {"v7-3": True, "v7-4": True})
    new = {name: _student_variant(assignment_id, name) for name in ("s2", "s3")}
    assert sorted(new.values()) == ["v7-3", "v7-4"], new  # the least used: the new variants
    assert {name: _student_variant(assignment_id, name) for name in first} == first  # nobody's lab changed


def test_students_get_a_variant_once_the_minimum_is_kept_though_others_are_still_measured(api):
    assignment_id = pool_assignment(api)
    assert generate(api, assignment_id, k=3, minimum=2).status_code == 201
    pool_id = _pool_id(assignment_id)
    _open(assignment_id)
    _decide(pool_id, {"v7-1": True})
    from grader.services.errors import Conflict

    with pytest.raises(Conflict, match="still being measured"):
        _student_variant(assignment_id, "alice")
    _decide(pool_id, {"v7-2": True})
    assert _student_variant(assignment_id, "alice") in ("v7-1", "v7-2")


@pytest.mark.parametrize("body, field", [({"k": 4, "budget": 3}, "budget"), ({"k": 4, "budget": 17}, "budget"),
                                         ({"k": 4, "minimum": 5}, "minimum")])
def test_a_budget_or_minimum_out_of_range_is_refused_naming_the_field_and_nothing_is_stored(api, body, field):
    assignment_id = pool_assignment(api)
    response = generate(api, assignment_id, **body)
    assert response.status_code == 422, response.text
    assert [e["field"] for e in response.json()["errors"]] == [field], response.text
    assert api.client.get(f"/v1/assignments/{assignment_id}/variants", headers=api.as_("prof")).json() is None
