"""Grade exports for instructors: a course's grades as CSV, an assignment's counted grades as CSV, one submission as
Gradescope results.json, and the evidence files of a case run (from the database). The API and the pages serve the
same bytes.

Scores are the current grade's, so an instructor's override (grader.services.submissions.overrides) is in them; the course CSV
adds an `overrides` column and Gradescope each overridden test's output the comment, beside the measured verdict."""

from __future__ import annotations

import csv
import io
from collections.abc import Mapping

from sqlalchemy import select
from sqlalchemy.orm import Session

from grader.core.lifecycle import evidence_bytes, evidence_of
from grader.core.grades import current_grade
from grader.core.variants import measuring_submissions
from grader.core.models import Assignment, CaseRun, Course, Grade, Submission, utcnow
from grader.services.setup import assignments
from grader.services.errors import Conflict, NotFound
from grader.services.submissions.visibility import readers, runs_answering, visibility_of, withheld_by
from rubric.exports import csv_text, grades_csv, gradescope_results
from rubric.scoring import GradeReport

# A case run's evidence files (grader.core.lifecycle.EVIDENCE_FILES) with their media types; nothing else is served.
EVIDENCE = {"arrays.npz": "application/octet-stream", "provenance.json": "application/json",
            "metrics.json": "application/json",
            "spec.json": "application/json", "stdout.txt": "text/plain", "stderr.txt": "text/plain"}
COUNTED_COLUMNS = ("student", "counted_score", "raw_score", "max_score", "penalty", "late_seconds", "attempt",
                   "submission_id", "submitted_at_utc")


def _report(grade: Grade):
    return GradeReport.model_validate(grade.report)


def course_grades_csv(*, session: Session, course: Course, latest: bool = False) -> tuple[str, str]:
    """(file name, CSV) of the course's current grades with each row's submission id and time (UTC): every graded
    submission in submission order, or with `latest` each student's latest graded attempt. A `variant` column names
    each row's lab variant once any row has one (rubric.exports.grades_csv); a pool's measuring submissions are not
    rows."""

    graded = session.execute(select(Submission, Grade).join(Grade, Grade.submission_id == Submission.id)
                             .where(Submission.course_id == course.id, Grade.superseded_at.is_(None),
                                    Submission.id.not_in(measuring_submissions()))  # a pool's own checks
                             .order_by(Submission.id)).all()
    if latest:  # each student's latest graded attempt of each lesson the course teaches
        graded = sorted({(s.student_id, s.lesson): (s, g) for s, g in graded}.values(),
                        key=lambda sg: (sg[0].student.name, sg[0].lesson))
    text = grades_csv([(s.student.name, _report(g)) for s, g in graded],
                      submissions=[(s.id, f"{s.created_at.isoformat()}+00:00") for s, _ in graded])
    return f"{course.name}-{'latest' if latest else 'all'}-grades.csv", _with_overrides(text, [g for _, g in graded])


def _overridden(grade: Grade) -> list[dict]:
    return [i for i in grade.report.get("items", []) if "override" in i]


def override_note(item: dict) -> str:
    """One overridden item in words: its score, the comment, who, and what was measured."""
    o = item["override"]
    return (f"{item['id']}: {o['score']:g} of {item['points']:g} set by {o['by']}: {o['comment']} "
            f"(measured: {item['verdict'].replace('_', ' ')}, {item['measured_score']:g})")


def _with_overrides(text: str, grades: list[Grade]) -> str:
    """The rubric's CSV with a last column `overrides` (each overridden item in words, "; " between), and an overridden
    item's cell holding its score even where the measurement alone was inconclusive (left empty there)."""
    rows = list(csv.reader(io.StringIO(text)))
    header = rows[0] + ["overrides"]
    mixed = "lesson" in rows[0]  # a file of two lessons names each item's column with its lesson (grades_csv)
    for row, grade in zip(rows[1:], grades, strict=True):
        items = _overridden(grade)
        for item in items:
            column = f"{grade.report.get('lesson')}.{item['id']}" if mixed else item["id"]
            if column in header:
                row[header.index(column)] = f"{item['score']:g}"
        row.append("; ".join(override_note(i) for i in items))
    return csv_text([header, *rows[1:]])


def counted_grades_csv(*, session: Session, assignment: Assignment) -> tuple[str, str]:
    """(file name, CSV) of the assignment's counted grades: student, counted score, raw score, penalty, attempt,
    submission and when it was submitted (UTC); and a last `variant` column once any row was graded on a variant."""
    counted = [assignments.counted_public(c) for c in assignments.counted_grades(session=session, assignment=assignment)]
    on_variants = any(r.variant for r in counted)
    rows: list[list] = [[*COUNTED_COLUMNS, *(["variant"] if on_variants else [])]]
    for r in counted:
        rows.append([r.student, f"{r.counted_score:g}", f"{r.raw_score:g}", f"{r.max_score:g}", f"{r.penalty:g}",
                     r.late_seconds, r.attempt, r.submission_id, r.submitted_at.isoformat(),
                     *([r.variant or ""] if on_variants else [])])
    return f"{assignment.course.name}-assignment-{assignment.id}-grades.csv", csv_text(rows)


def gradescope(*, session: Session, submission: Submission) -> dict:
    """Gradescope results.json of one graded submission, for the Gradescope assignment of the submission's own
    assignment: Gradescope's gates (`after_due_date`, `after_published`) are that assignment's own, so each test is
    gated as the site gates the item (issue 44, hostile pass 11):

    - an item its own assignment withholds takes that gate (after_due: after_due_date, on_release: after_published);
      so does an item whose verdict would tell such an item's answer (`readers`);
    - an item another assignment of the lesson withholds from the student now, or a reader of one, or an item held
      by both gates at once, is `hidden`: no gate of this Gradescope assignment is that assignment's due date or
      release (export again once it is shown);
    - a test whose evidence reads runs held otherwise than the test itself (a conceptual item's, whose verdict is the
      answer key's) keeps its verdict, not their numbers, as the report page masks it.

    A student's extension is no gate either: while it runs, what waits for its due date is `hidden`. A free
    submission has no gate of its own: what is withheld from the student now is `hidden`. The results' own
    output and score follow (rubric.exports.gradescope_results). Conflict while not graded."""
    grade = current_grade(session, submission.id)
    if grade is None:
        raise Conflict(f"submission {submission.id} is {submission.status}, not graded")
    report = _report(grade)
    runs = submission.case_runs
    names, kinds = [r.name for r in runs], {r.name: r.kind for r in runs}
    own, now = submission.assignment, utcnow()
    held: dict[str, set[str]] = {"after_due_date": set(), "after_published": set(), "hidden": set()}
    if own is not None:
        # Gradescope's after_due_date opens at its assignment's due date, not at this student's extension: while the
        # extension runs, what waits for it is hidden (pass 12)
        due = assignments.dates_for(session=session, assignment=own, student=submission.student)
        extended = due.extension is not None and due.due_at != own.due_at and now < due.due_at
        for item in assignments.item_ids(own.lesson, own.part):
            gate = assignments.GRADESCOPE_VISIBILITY[visibility_of(own, item)]
            if gate == "after_due_date" and extended:
                gate = "hidden"
            if gate != "visible":
                held[gate].add(item)
    for other in session.scalars(select(Assignment).where(
            Assignment.course_id == submission.course_id, Assignment.lesson == submission.lesson,
            Assignment.id != (own.id if own is not None else -1))):
        held["hidden"] |= set(withheld_by(session=session, assignment=other, student=submission.student, now=now))
    gates: dict[str, set[str]] = {}
    held_runs: dict[str, set[str]] = {}  # per gate, the runs withheld while the items held at it are (the kind rule)
    for gate, items in held.items():
        for item in [*items, *readers(submission.lesson, items, names, kinds)]:
            gates.setdefault(item, set()).add(gate)
        held_kinds = {kinds[r] for reads in runs_answering(submission.lesson, items, names).values() for r in reads}
        held_runs[gate] = {r for r in names if kinds[r] in held_kinds}
    shown = {i: next(iter(g)) if len(g) == 1 else "hidden" for i, g in gates.items()}
    masked = []
    for item in report.items:
        seen = shown.get(item.id, "visible")
        touched = set().union(*(runs_ for gate, runs_ in held_runs.items() if gate != seen)) & set(item.backends)
        masked.append(item if seen == "hidden" or not touched else item.model_copy(update={
            "measured": "", "evidence": {}, "feedback": (
                f"Verdict: {item.verdict.replace('_', ' ')}. Evidence withheld: it reads the measurements of "
                f"{', '.join(sorted(touched))}, which decide items not shown yet.")}))
    report = report.model_copy(update={"items": masked})
    results = gradescope_results(report, grade.execution_s, {i.id: shown.get(i.id, "visible") for i in report.items})
    overridden = {i["id"]: i for i in _overridden(grade)}
    for test in results["tests"]:
        item = overridden.get(test["name"].split(":", 1)[0])
        if item is not None:
            test["output"] = f"Score set by an instructor. {override_note(item)}\n{test['output']}"
    return results


def evidence_names(run: CaseRun) -> list[str]:
    """The evidence files a case run has in the database (its own, or its reused measurement's), in EVIDENCE order."""
    evidence = evidence_of(run)
    return [name for name in EVIDENCE if name in evidence.sizes] if evidence is not None else []


def evidence_file(*, submission: Submission, name: str, filename: str,
                  withheld: Mapping[str, str] | None = None) -> tuple[bytes, str]:
    """(bytes, media type) of one evidence file of the submission's case run `name`, read from the database (the
    worker's folder may be gone); NotFound otherwise. Conflict for a run in `withheld` ({run name: why}, the reader's
    GradeView.withheld_runs): its measurements decide an item withheld from the reader, and every file of it (the
    arrays, metrics, provenance, captured output) would tell them."""
    run: CaseRun | None = next((r for r in submission.case_runs if r.name == name), None)
    if run is None or filename not in EVIDENCE:
        raise NotFound(f"no file {filename!r} for case run {name!r}")
    if withheld and name in withheld:
        raise Conflict(f"the measurements of case run {name!r} are withheld: it {withheld[name]}")
    evidence = evidence_of(run)
    body = evidence_bytes(evidence, filename) if evidence is not None else None
    if body is None:
        raise NotFound(f"{filename} was not stored for case run {name!r}")
    return body, EVIDENCE[filename]
