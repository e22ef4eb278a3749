"""Which variant of an assignment's pool a student works on (issue 34): fixed once per (assignment, student), at their
first form view or submission, evenly and deterministically over the kept variants. Read by the submission service
(grader.services.submissions.submit) and the pages that show a student their own parameters.
"""

from __future__ import annotations

import hashlib
from collections import Counter

from sqlalchemy import select
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

import rubric
from grader.core.models import Assignment, PoolVariant, StudentVariant, User, VariantPool
from grader.core.states import PoolState, VariantState
from grader.core.variants import as_variant, serves_students
from grader.services.errors import Conflict, NotFound


def variant_for(*, session: Session, assignment: Assignment, student: User) -> PoolVariant | None:
    """The student's variant of `assignment`, fixed at the first call (their first form view or submission); None when
    the assignment has no pool. Conflict while the pool is still measuring or keeps no variant.

    Even and deterministic: the kept variant with the fewest students so far, ties broken by a hash of (assignment,
    student, variant id), so a class spreads over the pool and the same history gives the same assignment. A pool
    topped up later (issue 47) serves its new variants to the next students, the least used, while nobody's changes.
    Served once grader.core.variants.serves_students says so (its minimum kept, or ready)."""
    if assignment.course_id != student.course_id:
        raise NotFound("assignment not found")
    fixed = session.scalar(select(StudentVariant).where(StudentVariant.assignment_id == assignment.id,
                                                        StudentVariant.student_id == student.id))
    if fixed is not None:
        return fixed.variant
    pool = session.scalar(select(VariantPool).where(VariantPool.assignment_id == assignment.id))
    if pool is None:
        return None
    kept = [v for v in pool.variants if v.state == VariantState.KEPT]
    if not serves_students(pool):
        # Never a dead end (issue 47): the instructor's pool page offers the next step (a top-up); the student is told
        # the lab is being prepared, not that someone must start again.
        why = ("its variants are still being measured" if pool.state != PoolState.READY
               else "your instructor is preparing more variants of it (the pool page offers them a top-up)")
        rule = f"assignment {assignment.id} has no lab for you yet: {why}"
        raise Conflict(rule, [{"field": "assignment_id", "rule": rule}])
    counts = Counter(session.scalars(select(StudentVariant.variant_id)
                                     .where(StudentVariant.assignment_id == assignment.id)).all())

    def order(v: PoolVariant) -> tuple[int, str]:
        tie = hashlib.sha256(f"{assignment.id}|{student.id}|{v.name}".encode()).hexdigest()
        return counts.get(v.id, 0), tie

    chosen = min(kept, key=order)
    try:
        with session.begin_nested():
            session.add(StudentVariant(assignment_id=assignment.id, student_id=student.id, variant_id=chosen.id))
    except IntegrityError:  # fixed concurrently by another request of the same student: theirs stands
        fixed = session.scalar(select(StudentVariant).where(StudentVariant.assignment_id == assignment.id,
                                                            StudentVariant.student_id == student.id))
        return fixed.variant
    return chosen


def student_variant(*, session: Session, assignment: Assignment, student: User) -> rubric.Variant | None:
    """`variant_for` as the rubric's Variant (what the pages show with rubric.variants.texts); None without a pool."""
    row = variant_for(session=session, assignment=assignment, student=student)
    return as_variant(row) if row is not None else None
