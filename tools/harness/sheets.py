"""Sheets made for a lab variant (issue 34), shared by the variant tests and the benchmark's class on variants."""

from __future__ import annotations

from pathlib import Path

import yaml

import rubric

REFERENCE_SHEET = Path(__file__).resolve().parent.parent.parent / "examples" / "l03" / "reference.yaml"


def sheet_right_for(parameters: dict) -> dict:
    """The reference sheet with the answers that depend on the lab's numbers (C1: N4's timing, C5: the low lane's
    pair value, H1: the exercise's pair values, X1: the extension's timing) right for a variant with `parameters`,
    and its exercise and extension configs made from that variant's baseline (the pool's measured ones)."""
    from grader.services.setup.variants import measuring_sheet

    variant = rubric.Variant(id="v0-0", parameters=parameters)
    cases = variant.cases()
    n4, n5 = cases["N4"], cases["N5"]
    sheet = yaml.safe_load(REFERENCE_SHEET.read_text())
    answers = sheet["answers"]
    answers["C1"] = {"substep_dt": {"value": n4.dt / n4.substeps, "unit": "s"}, "samples": n4.n_steps,
                     "internal_updates": n4.n_steps * n4.substeps}
    answers["C5"] = {"pair_friction": parameters["table_friction"]}
    high = parameters["high_lane_friction"]
    answers["H1"] = {"baseline": {"low": parameters["table_friction"], "high": high},
                     "modified": {"low": parameters["exercise_table_friction"], "high": high}}
    answers["X1"] = {**answers["X1"], "substep_dt": {"value": round(n5.dt / n5.substeps * 1000, 6), "unit": "ms"},
                     "samples": n5.n_steps, "internal_updates": n5.n_steps * n5.substeps}
    sheet["configs"] = measuring_sheet(variant)["configs"]
    return sheet


def open_with_variants(engine, assignment_id: int, students: list[str]) -> dict[str, tuple[str, dict]]:
    """Open an assignment whose pool is ready (its open_at moved a year back, as a pool is measured before its
    assignment opens) and fix each named student's variant as at their first visit (grader.services.setup):
    {student name: (variant id, parameters)}."""
    from datetime import timedelta

    from sqlalchemy import select
    from sqlalchemy.orm import Session

    from grader.core.models import Assignment, User
    from grader.services.setup import student_variants

    with Session(engine) as session:
        assignment = session.get(Assignment, assignment_id)
        assignment.open_at -= timedelta(days=365)
        session.commit()
        given = {}
        for name in students:
            student = session.scalar(select(User).where(User.name == name))
            fixed = student_variants.variant_for(session=session, assignment=assignment, student=student)
            given[name] = (fixed.name, fixed.parameters)
        session.commit()
    return given
