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


def test_copy_evidence_grades_a_sheet_on_another_variant_only_on_runs_of_the_very_specs_it_needs(api):
    """grader.core.variants.runs_on (what flag_copying grades a variant sheet on, for every other kept variant): a
    config of the student's that fits the other variant is taken from the student's own run of that spec, never from
    the other variant's measuring run of the same name and another spec."""
    from datetime import timedelta

    from grader.core.db import new_session
    from grader.core.models import Assignment, PoolVariant, Submission, User, VariantPool
    from grader.core.variants import as_variant, runs_on
    from grader.services.setup import variants
    from tests.grader.services.setup.test_variants import Recorded, _all_kept_but

    assignment_id, pool_id = _services_pool(api, k=2)
    with new_session() as session:
        prof = session.scalar(select(User).where(User.name == "prof"))
        variants.measure(session=session, pool=session.get(VariantPool, pool_id), user=prof, sender=Recorded())
    _all_kept_but(pool_id, "none")
    with new_session() as session:
        session.get(Assignment, assignment_id).open_at -= timedelta(hours=2)
        session.commit()
    # alice's variant is fixed at her first visit; her sheet is made from the other variant's lab, with its table
    # exercise at another table friction than that variant's own exercise (still one factor from its baseline)
    with new_session() as session:
        from grader.services.setup.student_variants import variant_for

        alice = session.scalar(select(User).where(User.name == "alice"))
        own = variant_for(session=session, assignment=session.get(Assignment, assignment_id), student=alice)
        other = session.scalar(select(PoolVariant).where(PoolVariant.pool_id == pool_id, PoolVariant.id != own.id))
        session.commit()
        sheet = variants.measuring_sheet(as_variant(other))
    sheet["configs"]["table_exercise"]["table"]["friction"] = round(
        sheet["configs"]["table_exercise"]["table"]["friction"] + 0.05, 2)
    posted = api.client.post("/v1/submissions", json={"sheet": sheet, "assignment_id": assignment_id},
                             headers=api.as_("alice"))
    assert posted.status_code == 202, posted.text

    book = rubric.load_rubric("L03")
    with new_session() as session:
        submission = session.get(Submission, posted.json()["id"])
        other = session.get(PoolVariant, other.id)
        parsed = rubric.parse_sheet(submission.sheet, submission.part)
        needed = {s.name: s.model_dump(mode="json", exclude_computed_fields=True)
                  for s in rubric.cases_to_run(parsed, book, as_variant(other))}
        measuring = session.get(Submission, other.submission_id)
        theirs = {run.name: run.spec for run in measuring.case_runs}
        # the case this is about: needed under the other variant, a run of that name there, of another spec
        assert "sheet.table_exercise" in needed and needed["sheet.table_exercise"] != theirs["sheet.table_exercise"]
        found = runs_on(session, other, parsed, book, submission)
        assert found, "the other variant's lesson runs are stored"
        for name, result in found.items():
            assert result.spec.model_dump(mode="json", exclude_computed_fields=True) == needed[name], name
        assert "sheet.table_exercise" not in found or found["sheet.table_exercise"].spec.table.friction == \
            sheet["configs"]["table_exercise"]["table"]["friction"]
