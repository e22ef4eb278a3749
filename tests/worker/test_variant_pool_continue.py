"""K means kept (issue 47), the worker's part: once a measuring submission's lab check dropped its variant, the worker
draws the pool further and sends the new variant's runs behind every student's (POOL_PRIORITY); when the pool may
still keep K, nothing is drawn or sent."""

from __future__ import annotations

from sqlalchemy import select

from tests.grader.services.setup.test_variant_pool_budget import _decide, _pool_id
from tests.grader.services.setup.test_variants import generate, pool_assignment


def test_a_dropped_variant_makes_the_worker_draw_and_send_the_next_one_behind_students(tmp_path, monkeypatch):
    from grader.core import lifecycle
    from grader.core.db import new_session
    from grader.core.models import CaseRun, PoolVariant
    from tests.grader.conftest import app_on
    from worker import tasks

    with app_on(f"sqlite:///{tmp_path / 'grader.db'}", tmp_path, monkeypatch) as api:
        aid = pool_assignment(api)
        assert generate(api, aid, k=2, budget=3).status_code == 201
        sent, graded = [], []
        monkeypatch.setattr(tasks.run_case_run, "apply_async", lambda **kwargs: sent.append(kwargs))
        monkeypatch.setattr(tasks.grade_submission, "apply_async", lambda **kwargs: graded.append(kwargs))

        (kept_submission,) = _decide(_pool_id(aid), {"v7-2": True})
        tasks._continue_pool(kept_submission)  # 1 kept + 1 measuring: K may still be kept
        assert sent == [] and graded == []

        (dropped_submission,) = _decide(_pool_id(aid), {"v7-1": False})
        tasks._continue_pool(dropped_submission)
        with new_session() as session:
            third = session.scalar(select(PoolVariant).where(PoolVariant.name == "v7-3"))
            assert third is not None and third.state == "measuring" and third.submission_id is not None
            queued = session.scalars(select(CaseRun.id).where(CaseRun.submission_id == third.submission_id,
                                                              CaseRun.status == "queued")).all()
        assert queued and sorted(kw["args"][0] for kw in sent) == sorted(queued)
        assert {(kw["queue"], kw["priority"]) for kw in sent} == {("cpu", lifecycle.POOL_PRIORITY)}

        sent.clear()
        tasks._continue_pool(dropped_submission)  # a redelivered task: the pool is full again, nothing more
        assert sent == []


def test_a_pools_lab_check_is_sent_ahead_of_every_pools_runs_and_a_students_behind_every_case(tmp_path, monkeypatch):
    """Issue 47: a pool whose runs were reused waited about 9 minutes for its lab checks behind another pool's runs
    (both at POOL_PRIORITY). The grade task sends a measuring submission's completion at POOL_CHECK_PRIORITY, ahead
    of the pools' runs; a student's still goes last (COMPLETE_PRIORITY), so at a deadline every case comes first."""
    from grader.core import lifecycle
    from grader.core.db import new_session
    from grader.core.models import PoolVariant
    from tests.grader.conftest import app_on
    from tests.factories import reference_sheet
    from worker import tasks

    assert lifecycle.POOL_CHECK_PRIORITY < lifecycle.POOL_PRIORITY and lifecycle.POOL_CHECK_PRIORITY < (
        lifecycle.COMPLETE_PRIORITY)
    with app_on(f"sqlite:///{tmp_path / 'grader.db'}", tmp_path, monkeypatch) as api:
        aid = pool_assignment(api)
        assert generate(api, aid, k=1).status_code == 201
        with new_session() as session:
            measuring = session.scalar(select(PoolVariant.submission_id).where(PoolVariant.submission_id.is_not(None)))
        made = api.client.post("/v1/submissions", json={"sheet": reference_sheet()}, headers=api.as_("alice"))
        assert made.status_code == 202, made.text
        completions = []
        monkeypatch.setattr(tasks.complete_grade, "apply_async", lambda **kwargs: completions.append(kwargs))
        monkeypatch.setattr(tasks, "_continue_pool", lambda submission_id: None)
        for submission_id in (measuring, made.json()["id"]):  # neither is 'grading' yet: nothing graded, both sent
            tasks.grade_submission(submission_id)
        assert [(kw["args"], kw["queue"], kw["priority"]) for kw in completions] == [
            ([measuring], "cpu", lifecycle.POOL_CHECK_PRIORITY), ([made.json()["id"]], "cpu", lifecycle.COMPLETE_PRIORITY)]
