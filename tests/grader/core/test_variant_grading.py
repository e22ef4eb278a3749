"""Grading reads a submission's variant from its row (grader.core.grading.score, which the worker's grade task, a
checkpoint sheet graded at once and a regrade all use): the same stored runs are graded under the variant the row names,
and the lesson's shipped runs never stand in for a variant's."""

from __future__ import annotations

from sqlalchemy import select

import rubric
from tests.grader.services.setup.test_variants import _services_pool


def test_a_submissions_variant_decides_what_its_stored_runs_are_graded_against(api, lesson_measured):
    from grader.core.db import new_session
    from grader.core.grading import score
    from grader.core.models import CaseRun, PoolVariant, Submission

    _, pool_id = _services_pool(api, k=1)
    book = rubric.load_rubric("L03")
    with new_session() as session:
        measured = session.get(Submission, session.get(CaseRun, lesson_measured["N1"]).submission_id)
        shipped = score(measured, book)  # the lesson's own runs, no variant: as before pools
        verdicts = {i.id: i.verdict for i in shipped.items}
        assert shipped.variant is None and verdicts["A2"] != "not_measured" and verdicts["C1"] == "credit"

        row = session.scalar(select(PoolVariant).where(PoolVariant.pool_id == pool_id))
        measured.variant_id = row.id
        session.flush()
        session.expire(measured, ["variant"])
        under = score(measured, book)
        assert under.variant == row.name
        refused = [i for i in under.items if i.verdict == "not_measured"]
        # every item read from a contact run: its runs were measured with the shipped parameters, not the variant's
        assert {"A2", "C1"} <= {i.id for i in refused}
        assert all("other parameters" in i.measured or "other parameters" in i.feedback
                   for i in refused if i.id in ("A2", "C1")), [(i.id, i.measured, i.feedback) for i in refused]
        session.rollback()
