"""A course's class dashboard, read from storage once and served both as JSON (/v1) and as the page.

Counts submissions by state, lists case runs that failed or are stuck with their reason (and whether an instructor
may re-send them), takes each student's latest graded attempt for the item analysis (rubric.analysis), the roster
and the predictions against what was measured (H1, H4), and spreads the course's key measurements by the backend
that produced them, and gives each assignment's counted grades. The charts (grader.pages.reports.dashboard) are drawn
from this same data, never from a second query. At its top, what changed that a person must look at: the open review
requests and the newest overrides (grader.services.submissions.review_requests, grader.services.submissions.overrides).
For an assignment on per-student variants (issue 34): its copy evidence, and its counted sheets grouped by variant
(n, mean total and each item's mean), so a harder variant shows. A pool's measuring submissions (the instructor's,
grader.core.variants.measuring_submissions) are no student's work: they are left out of every count, list and
distribution, and listed among the failed or stuck runs only as the pool's, named by variant.
"""

from __future__ import annotations

import logging
import statistics
from collections import Counter
from datetime import UTC, datetime
from typing import Any, Literal

from pydantic import BaseModel
from sqlalchemy import select
from sqlalchemy.orm import Session, selectinload

from grader.core import lifecycle
from grader.core.states import CaseRunState, SubmissionState, VariantState
from grader.core.models import (Assignment, CaseRun, CopyFlag, Course, Grade, PoolVariant, Submission, User,
                                VariantPool, utcnow)
from grader.core.variants import measuring_submissions, send_priority
from grader.core.schemas import CountedGradePublic, UtcDateTime
from grader.services.identity.access import MAX_ID, require_instructor
from grader.services.setup.assignments import counted_grades, counted_public
from grader.services.setup.variants import FlagRow
from grader.services.errors import Conflict, NotFound
from grader.services.submissions import overrides as override_store
from grader.services.submissions import review_requests
from grader.services.submissions.overrides import OverridePublic
from grader.services.submissions.review_requests import ReviewRequestPublic
from grader.services.sending import Sender
from grader.services.identity import access
from grader.core.timezones import zone
from rubric import class_analysis
from rubric.analysis import ScoreBin, score_distribution
from rubric import sheet as sheet_models
from rubric.scoring import GradeReport


class RosterRow(BaseModel):
    student: str
    submission_id: int
    status: str
    submitted_at: UtcDateTime
    attempts: int
    total: float | None
    max_total: float | None


class RunProblem(BaseModel):
    case_run_id: int
    submission_id: int
    student: str
    case: str
    status: str
    reason: str
    since: UtcDateTime
    delivery: int
    resendable: bool
    not_resendable_because: str | None = None
    measures_variant: str | None = None  # a run of a pool's measuring submission: the variant it measures


class PredictionRow(BaseModel):
    """One predicted number of one student's latest graded attempt, next to the value the grade measured."""

    item: str
    student: str
    submission_id: int
    run: Literal["baseline", "modified"]
    lane: Literal["low", "high"]
    case: str
    backend: str | None
    predicted_as_written: str  # as the sheet wrote it: "41 cm", "not stopped", "0.5"
    predicted: float | None  # in `unit` (SI); None for "not stopped"
    measured: float | None  # in `unit`; None when not stopped or not measured
    measured_text: str  # "0.4103 m", "not stopped", "not measured"
    difference: float | None  # predicted - measured, where both are numbers
    tolerance: float  # the reviewed tolerance the grade used, in `unit`
    within_tolerance: bool | None  # None: nothing to compare (not measured)
    verdict: str  # the item's verdict in the grade


class PredictionPlot(BaseModel):
    item: str
    question: str
    quantity: str
    unit: str  # "m", or "" for a dimensionless coefficient
    tolerance_name: str
    tolerances: list[float]  # every distinct tolerance the plotted grades used (one unless rubric versions differ)
    chart: str  # URL of the chart (instructors of the course only)
    rows: list[PredictionRow]


class MeasurementGroup(BaseModel):
    """One key measurement of one case (and lane) on one backend, over the course's distinct measurements."""

    metric: Literal["penetration_proxy", "stop_distance"]
    case: str
    lane: str | None
    backend: str
    unit: str
    values: list[float]  # one per distinct measurement (a reused run counts once); stops only where stopped
    not_stopped: int
    n: int  # distinct measurements, stopped or not
    min: float | None
    median: float | None
    max: float | None


class BackendSpread(BaseModel):
    chart: str
    groups: list[MeasurementGroup]


class AssignmentGrades(BaseModel):
    """One assignment of the course with each student's counted grade (grader.services.setup.assignments.counted_grades)."""

    id: int
    title: str
    part: str
    due_at: UtcDateTime
    counted_attempt: str
    page: str  # the instructor's page of the assignment
    grades: list[CountedGradePublic]


class ScoreGroup(BaseModel):
    """One score distribution of like with like: an assignment's counted scores (one per student), or the latest
    graded submission per student outside assignments (sheets only: they are all scored out of one maximum)."""

    assignment_id: int | None
    title: str
    part: str
    n: int
    max_total: float
    mean: float
    median: float
    distribution: list[ScoreBin]


class VariantScores(BaseModel):
    """One variant of an assignment's pool: its students' counted sheets (n), their mean total, each item's mean."""

    variant: str
    state: str  # kept, or dropped (listed only while a student still has it)
    n: int
    mean: float | None
    difference: float | None  # mean minus the assignment's mean over every variant's sheets
    items: dict[str, float | None]  # item id -> mean score (inconclusive verdicts left out, as in the item analysis)


class AssignmentVariants(BaseModel):
    """An assignment on per-student variants: per variant its counted sheets, and the copy evidence of its
    submissions (their current grades'; evidence for the instructor, never a change of grade)."""

    id: int
    title: str
    page: str
    n: int
    mean: float | None
    max_total: float | None
    items: list[str]  # item ids in the rubric's order
    item_points: dict[str, float]
    variants: list[VariantScores]
    flags: list[FlagRow]


class LessonAnalysis(BaseModel):
    """The item analysis (rubric.analysis.ClassAnalysis) of one lesson of the course, over each student's latest
    graded attempt of that lesson: items are compared with the same lesson's items only (one lesson's C1 is not
    another's)."""

    lesson: str
    analysis: dict[str, Any]


class Dashboard(BaseModel):
    course: str
    lesson: str | None  # the lesson of the course's latest submission; `analysis` is that lesson's
    lessons: list[str] = []  # every lesson the course's submissions are of, in order
    students_graded: int = 0  # students with a graded attempt of any lesson
    rubric_versions: list[str]
    submissions_by_state: dict[str, int]
    submissions_per_day: dict[str, int]
    problems: list[RunProblem]
    roster: list[RosterRow]
    analysis: dict[str, Any]
    analyses: list[LessonAnalysis] = []  # one per lesson with a graded attempt, in `lessons`' order
    predictions: list[PredictionPlot]
    backends: BackendSpread
    assignments: list[AssignmentGrades] = []
    score_groups: list[ScoreGroup] = []  # per assignment and for submissions outside one: never mixed maxima
    open_reviews: list[ReviewRequestPublic] = []  # oldest first: the queue at /courses/COURSE/reviews
    recent_overrides: list[OverridePublic] = []  # newest first, the ones in force
    variants: list[AssignmentVariants] = []  # the course's assignments with a variant pool


# --- grades: every Grade query of this module goes through current_grades / current_grade ------------------------

def current_grades(session: Session, *, course_id: int) -> dict[int, Grade]:
    """The grade each graded submission of a course stands on (not superseded by a regrade), by submission id.
    One submission's is grader.core.grades.current_grade."""
    query = (select(Grade).join(Submission, Grade.submission_id == Submission.id)
             .where(Submission.course_id == course_id, Grade.superseded_at.is_(None)))
    return {g.submission_id: g for g in session.scalars(query)}


def latest_graded(session: Session, course: Course) -> list[tuple[Submission, Grade]]:
    """Each student's latest graded attempt of each lesson (the one the item analysis counts), ordered by student
    name, then lesson. A course that runs two lessons keeps one attempt of each: a sheet of one lesson never stands
    for the student's attempt of the other."""
    grades = current_grades(session, course_id=course.id)
    latest: dict[tuple[int, str], tuple[Submission, Grade]] = {}
    for s in session.scalars(select(Submission).where(Submission.course_id == course.id,
                                                      Submission.id.in_(list(grades)),
                                                      Submission.id.not_in(measuring_submissions()))
                             .order_by(Submission.id)):
        latest[(s.student_id, s.lesson)] = (s, grades[s.id])
    return sorted(latest.values(), key=lambda sg: (sg[0].student.name, sg[0].lesson))


# --- problems and the resend action --------------------------------------------------------------------------------

def _not_resendable(run: CaseRun, submission: Submission, now: datetime) -> str | None:
    """Why an instructor may not re-send this run now, or None when they may. (A submission with an instructor's
    scores in force may be: grading it again keeps them, grader.core.grading.store_grade.)"""
    if run.status != CaseRunState.FAILED and lifecycle.stuck_reason(run, now) is None:
        return f"case run {run.id} ({run.name}) is {run.status}, neither failed nor stuck"
    if submission.status == SubmissionState.GRADING:
        return f"submission {submission.id} is being graded; re-send once its grade is stored"
    return None


def case_run_of(session: Session, *, course: Course, case_run_id: int) -> CaseRun | None:
    """A case run of the course's submissions, or None."""
    run = session.get(CaseRun, case_run_id) if 0 < case_run_id <= MAX_ID else None
    return run if run is not None and run.submission.course_id == course.id else None


def resend_case_run(*, session: Session, case_run_id: int, user: User, sender: Sender) -> CaseRun:
    """An instructor of the run's course re-sends a failed or stuck case run (grader.core.lifecycle.resend): a new
    delivery on the same backend's queue, recorded in an event that names who did it and keeps the old error.
    NotFound, Forbidden or Conflict otherwise. Commits, then sends (so the message never precedes the state)."""
    run = session.get(CaseRun, case_run_id) if 0 < case_run_id <= MAX_ID else None
    if run is None or run.submission.course_id != user.course_id or (
            access.is_student(user) and run.submission.student_id != user.id):
        raise NotFound(f"case run {case_run_id} not found")
    require_instructor(user, action="re-send a case run")
    # Lock the submission, then the run (the order lifecycle._finish takes): a finisher and a resend serialize.
    lifecycle.lock_submission(session, run.submission_id)
    session.refresh(run, with_for_update=True)
    submission = run.submission
    session.refresh(submission)
    now = utcnow()
    why_not = _not_resendable(run, submission, now)
    if why_not:
        session.rollback()
        raise Conflict(why_not)
    lifecycle.resend(session, run, by=f"{user.role} {user.name}")
    session.commit()
    try:
        sender.send_case_run(run.id, run.delivery, run.backend, priority=send_priority(session, run))
    except Exception:  # noqa: BLE001 - stored as queued: the reconciler re-sends it after the queue lease

        logging.getLogger(__name__).exception("could not enqueue resent case run %s", run.id)
    return run


# --- predictions against measurements --------------------------------------------------------------------------------

# The items whose predictions are numbers the grade compared with a measurement: how to read each one's report.
# Evidence keys are the ones rubric.scoring.hands_on writes; a prediction is parsed with the sheet's own answer
# model (rubric.sheet), so units convert exactly as grading converted them (Quantity.si).
PREDICTED_ITEMS = {
    "H1": dict(quantity="effective pair friction", unit="", tolerance="pair_friction_abs",
               evidence="{run}_{lane}"),
    "H4": dict(quantity="sustained stop distance", unit="m", tolerance="reported_stop_distance",
               evidence="{run}_{lane}_stop_distance_m"),
}
RUN_CASES = {"baseline": "friction-baseline", "modified": "sheet.table_exercise"}


def _tolerance(text: str) -> float:
    """A report's tolerance, stored as 'VALUE UNIT' (rubric.scoring.scorer._tolerances), as a number in that unit."""
    return float(text.split()[0])


def _fmt(value: float, unit: str) -> str:
    return f"{value:.4g} {unit}".rstrip()


def _prediction_rows(item_id: str, submission: Submission, report) -> list[PredictionRow]:
    spec = PREDICTED_ITEMS[item_id]
    graded = report.item(item_id)
    answer = getattr(sheet_models, item_id).model_validate_json(graded.prediction)
    tolerance = _tolerance(graded.tolerances[spec["tolerance"]])
    rows = []
    for run in ("baseline", "modified"):
        for lane in ("low", "high"):
            said = getattr(getattr(answer, run), lane)
            if said == "not_stopped":
                predicted, written = None, "not stopped"
            elif isinstance(said, float):
                predicted, written = said, f"{said:g}"
            else:
                predicted, written = said.si, f"{said.value:g} {said.unit}"
            key = spec["evidence"].format(run=run, lane=lane)
            measured = graded.evidence.get(key)
            if key not in graded.evidence:
                measured_text, within = "not measured", None
            elif measured is None:  # a stop that was not sustained within the window
                measured_text, within = "not stopped", predicted is None
            else:
                measured_text = _fmt(measured, spec["unit"])
                within = predicted is not None and abs(predicted - measured) <= tolerance
            case = RUN_CASES[run]
            rows.append(PredictionRow(
                item=item_id, student=submission.student.name, submission_id=submission.id, run=run, lane=lane,
                case=case, backend=graded.backends.get(case), predicted_as_written=written, predicted=predicted,
                measured=measured, measured_text=measured_text,
                difference=predicted - measured if predicted is not None and measured is not None else None,
                tolerance=tolerance, within_tolerance=within, verdict=graded.verdict))
    return rows


def predictions(course: Course, graded: list[tuple[Submission, Any]]) -> list[PredictionPlot]:
    """H1 and H4 of each student's latest graded attempt: every predicted number against its measured value."""
    plots = []
    for item_id, spec in PREDICTED_ITEMS.items():
        rows: list[PredictionRow] = []
        question = ""
        for submission, report in graded:
            if not any(i.id == item_id for i in report.items):
                continue
            question = report.item(item_id).question
            rows.extend(_prediction_rows(item_id, submission, report))
        plots.append(PredictionPlot(
            item=item_id, question=question, quantity=spec["quantity"], unit=spec["unit"],
            tolerance_name=spec["tolerance"], tolerances=sorted({r.tolerance for r in rows}),
            chart=f"/courses/{course.name}/dashboard/charts/predictions-{item_id}.svg", rows=rows))
    return plots


# --- per-backend spread of the key measurements ----------------------------------------------------------------------

def backend_spread(session: Session, course: Course) -> BackendSpread:
    """Penetration proxy per contact case and stop distance per friction lane, grouped by the backend that produced
    them (the case run's actual_backend). A measurement reused by several runs counts once."""
    # Only the columns read here: a case run's provenance (captured output and all) is far larger than its metrics.
    runs = session.execute(
        select(CaseRun.id, CaseRun.name, CaseRun.actual_backend, CaseRun.measurement_id, CaseRun.metrics)
        .join(Submission, CaseRun.submission_id == Submission.id)
        .where(Submission.course_id == course.id, CaseRun.status == CaseRunState.DONE, CaseRun.metrics.is_not(None))
        .order_by(CaseRun.id)).all()
    seen: set[tuple] = set()
    values: dict[tuple[str, str, str | None, str], list[float | None]] = {}
    for run_id, name, actual_backend, measurement_id, metrics in runs:
        # The measurement a run stands on: its own, or the one it reused (the same stored numbers).
        origin = ("measurement", measurement_id) if measurement_id else ("run", run_id)
        if origin in seen:
            continue
        seen.add(origin)
        backend = actual_backend or "unknown"
        metrics = metrics or {}  # a JSON 'null' is not SQL NULL: the query above lets it through
        if metrics.get("kind") == "contact":
            values.setdefault(("penetration_proxy", name, None, backend), []).append(metrics["penetration_proxy"])
        elif metrics.get("kind") == "friction":
            for lane_name, lane in metrics.get("lanes", {}).items():
                stop = lane["stop"]
                values.setdefault(("stop_distance", name, lane_name, backend), []).append(
                    stop["distance"] if stop["stopped"] else None)
    groups = []
    lanes = {None: 0, "low": 1, "high": 2}
    for (metric, case, lane, backend), found in sorted(values.items(), key=lambda kv: (
            kv[0][0], _case_order(kv[0][1]), lanes.get(kv[0][2], 3), kv[0][2] or "", kv[0][3])):
        numbers = sorted(v for v in found if v is not None)
        groups.append(MeasurementGroup(
            metric=metric, case=case, lane=lane, backend=backend, unit="m", values=numbers,
            not_stopped=len(found) - len(numbers), n=len(found),
            min=numbers[0] if numbers else None, median=statistics.median(numbers) if numbers else None,
            max=numbers[-1] if numbers else None))
    return BackendSpread(chart=f"/courses/{course.name}/dashboard/charts/backends.svg", groups=groups)


def _case_order(name: str) -> tuple[int, str]:
    """Lesson cases first in the lesson's order, then the students' own configs."""
    lesson = ("N1", "N2", "N3", "N4", "N5", "friction-baseline", "friction-baseline-colors-swapped",
              "friction-table-0.30")
    return (lesson.index(name), "") if name in lesson else (len(lesson), name)


# --- the whole dashboard ------------------------------------------------------------------------------------------

def graded_reports(session: Session, course: Course) -> list[tuple[Submission, Any]]:
    return [(s, GradeReport.model_validate(g.report)) for s, g in latest_graded(session, course)]


def measured_variants(session: Session, course: Course) -> dict[int, str]:
    """The course's measuring submissions: the variant each measures, by submission id."""
    return dict(session.execute(select(PoolVariant.submission_id, PoolVariant.name)
                                .join(Submission, Submission.id == PoolVariant.submission_id)
                                .where(Submission.course_id == course.id)).all())


def course_dashboard(*, session: Session, course: Course) -> Dashboard:
    now = utcnow()
    every = session.scalars(select(Submission).where(Submission.course_id == course.id)
                            .options(selectinload(Submission.case_runs)).order_by(Submission.id)).all()
    measuring = measured_variants(session, course)
    submissions = [s for s in every if s.id not in measuring]  # the students' work (and staff's own tries)
    grades = current_grades(session, course_id=course.id)
    latest: dict[int, Submission] = {}
    attempts: Counter[int] = Counter()
    for s in submissions:
        latest[s.student_id] = s
        attempts[s.student_id] += 1
    graded = graded_reports(session, course)
    latest_free: dict[int, Grade] = {}  # per student, the latest graded submission outside assignments
    for s in submissions:
        if s.assignment_id is None and s.id in grades:
            latest_free[s.student_id] = grades[s.id]
    problems = []
    for s in every:  # a pool's stuck run is the instructor's to re-send too
        for run in s.case_runs:
            reason = run.error if run.status == CaseRunState.FAILED else lifecycle.stuck_reason(run, now)
            if reason:
                why_not = _not_resendable(run, s, now)
                problems.append(RunProblem(case_run_id=run.id, submission_id=s.id, student=s.student.name,
                                           case=run.name, status=run.status, reason=reason,
                                           since=run.finished_at or run.started_at or run.queued_at,
                                           delivery=run.delivery, resendable=why_not is None,
                                           not_resendable_because=why_not, measures_variant=measuring.get(s.id)))
    lesson = submissions[-1].lesson if submissions else None
    analyses = lesson_analyses(graded)
    return Dashboard(
        course=course.name,
        lesson=lesson,
        lessons=sorted({s.lesson for s in submissions}),
        students_graded=len({s.student_id for s, _ in graded}),
        rubric_versions=sorted({report.rubric_version for _, report in graded}),
        submissions_by_state=dict(Counter(s.status for s in submissions)),
        submissions_per_day=per_day(submissions, course.timezone),
        problems=problems,
        roster=[RosterRow(student=s.student.name, submission_id=s.id, status=s.status, submitted_at=s.created_at,
                          attempts=attempts[student], total=grades[s.id].total if s.id in grades else None,
                          max_total=grades[s.id].max_total if s.id in grades else None)
                for student, s in sorted(latest.items(), key=lambda kv: kv[1].student.name)],
        analysis=next((a.analysis for a in analyses if a.lesson == lesson), class_analysis([]).model_dump(mode="json")),
        analyses=analyses,
        predictions=predictions(course, graded),
        backends=backend_spread(session, course),
        assignments=(by_assignment := assignment_grades(session, course)),
        score_groups=score_groups(by_assignment, list(latest_free.values())),
        open_reviews=[review_requests.public(r) for r in
                      review_requests.course_requests(session=session, course_id=course.id, state="open")],
        recent_overrides=[override_store.public(session, o)
                          for o in override_store.recent_overrides(session, course_id=course.id)],
        variants=variant_scores(session, course, grades),
    )


def lesson_analyses(graded: list[tuple[Submission, Any]]) -> list[LessonAnalysis]:
    """The item analysis of each lesson over its own reports (each student's latest attempt of it), by lesson."""
    by_lesson: dict[str, list[GradeReport]] = {}
    for submission, report in graded:
        by_lesson.setdefault(submission.lesson, []).append(report)
    return [LessonAnalysis(lesson=lesson, analysis=class_analysis(reports).model_dump(mode="json"))
            for lesson, reports in sorted(by_lesson.items())]


def variant_scores(session: Session, course: Course, grades: dict[int, Grade]) -> list[AssignmentVariants]:
    """Each assignment of the course with a pool: its students' counted sheets grouped by their variant, and the
    copy evidence stored against its submissions' current grades, newest first."""
    out = []
    pools = session.execute(select(Assignment, VariantPool).join(VariantPool, VariantPool.assignment_id == Assignment.id)
                            .where(Assignment.course_id == course.id).order_by(Assignment.due_at, Assignment.id)).all()
    for assignment, pool in pools:
        counted = [c.submission for c in counted_grades(session=session, assignment=assignment)
                   if c.submission.id in grades]
        reports = {s.id: GradeReport.model_validate(grades[s.id].report) for s in counted}
        overall = class_analysis(list(reports.values()))
        rows = []
        for variant in pool.variants:
            mine = [reports[s.id] for s in counted if s.variant_id == variant.id]
            if variant.state != VariantState.KEPT and not mine:
                continue
            stats = class_analysis(mine)
            rows.append(VariantScores(
                variant=variant.name, state=variant.state, n=stats.n_reports, mean=stats.mean_total,
                difference=(stats.mean_total - overall.mean_total) if stats.mean_total is not None else None,
                items={i.id: i.mean_score for i in stats.items}))
        flags = session.scalars(select(CopyFlag).join(Submission, CopyFlag.submission_id == Submission.id)
                                .join(Grade, CopyFlag.grade_id == Grade.id)
                                .where(Submission.assignment_id == assignment.id, Grade.superseded_at.is_(None))
                                .order_by(CopyFlag.id.desc())).all()
        out.append(AssignmentVariants(
            id=assignment.id, title=assignment.title, page=f"/assignments/{assignment.id}", n=overall.n_reports,
            mean=overall.mean_total, max_total=overall.max_total, items=[i.id for i in overall.items],
            item_points={i.id: i.points for i in overall.items}, variants=rows,
            flags=[FlagRow(submission_id=f.submission_id, student=f.submission.student.name,
                           own_variant=f.submission.variant.name if f.submission.variant else "",
                           fits_variant=f.variant.name, items=f.items, own_expected=f.own_expected,
                           other_expected=f.other_expected, summary=f.summary, created_at=f.created_at)
                   for f in flags]))
    return out


def assignment_grades(session: Session, course: Course) -> list[AssignmentGrades]:
    """Every assignment of the course, by due date, with the counted grade of each student who has one."""

    rows = session.scalars(select(Assignment).where(Assignment.course_id == course.id)
                           .order_by(Assignment.due_at, Assignment.id)).all()
    return [AssignmentGrades(id=a.id, title=a.title, part=a.part, due_at=a.due_at, counted_attempt=a.counted_attempt,
                             page=f"/assignments/{a.id}",
                             grades=[counted_public(c) for c in counted_grades(session=session, assignment=a)])
            for a in rows]



def per_day(submissions: list[Submission], timezone: str) -> dict[str, int]:
    """Submissions per calendar day in the course's zone (the day a student saw on their clock), oldest first."""
    tz = zone(timezone)
    return dict(sorted(Counter(f"{s.created_at.replace(tzinfo=UTC).astimezone(tz):%Y-%m-%d}"
                               for s in submissions).items()))


def _group(assignment_id: int | None, title: str, part: str, scores: list[float], max_total: float) -> ScoreGroup:
    return ScoreGroup(assignment_id=assignment_id, title=title, part=part, n=len(scores), max_total=max_total,
                      mean=statistics.fmean(scores), median=statistics.median(scores),
                      distribution=score_distribution(scores, max_total))


def score_groups(assignments: list[AssignmentGrades], free: list[Grade]) -> list[ScoreGroup]:
    """A distribution per assignment (its counted scores) and one per maximum of the latest graded submission of each
    student outside assignments: a checkpoint attempt out of 8 is never a bin of a sheet out of 30."""
    out = []
    for a in assignments:
        if a.grades:
            out.append(_group(a.id, a.title, a.part, [g.counted_score for g in a.grades],
                              max(g.max_score for g in a.grades)))
    by_max: dict[float, list[float]] = {}
    for grade in free:
        by_max.setdefault(grade.max_total, []).append(grade.total)
    for max_total, totals in sorted(by_max.items()):
        out.append(_group(None, "", "", totals, max_total))
    return out
