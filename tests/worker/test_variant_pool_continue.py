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
