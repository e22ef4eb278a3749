"""Stored rows -> what a report page shows: case-run states with time spent, items with their tolerances, provenance.

Pure reads of the database rows and the stored grade; nothing here runs a case, grades or draws.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from datetime import datetime

from sqlalchemy import select
from sqlalchemy.orm import object_session

from grader.core.rubrics import stored_version
from grader.core.states import CaseRunState, SubmissionState
from grader.core.models import CaseRun, Grade, Override, ReviewRequest, Submission, utcnow
from grader.services.reports.exports import evidence_names
from grader.services.submissions.overrides import override_history
from grader.services.submissions.review_requests import state_of
from grader.services.submissions.visibility import GradeView
from rubric.metrics import TUMBLE_EXPLANATION, tumble_angle_deg

# A case still running after this long on a fresh worker is most likely compiling Genesis kernels (~100 s once).
FIRST_RUN_NOTE_AFTER_S = 20.0
VERDICT_LABEL = {
    "credit": "credit", "no_credit": "no credit", "inconclusive": "inconclusive (not counted)",
    "one_factor_violation": "config fault", "not_measured": "not measured", "pending": "pending",
}


@dataclass
class RunRow:
    name: str
    kind: str
    status: str
    result_status: str | None
    backend: str
    actual_backend: str | None
    elapsed_s: float | None
    error: str | None
    reused_from_id: int | None
    provenance: dict
    files: list[str]
    withheld: str | None = None  # why its measurements (provenance, files, metrics) are withheld from the reader


@dataclass
class ItemRow:
    id: str
    part: str
    kind: str
    question: str
    prediction: str  # the sheet's answer as the grade stores it (JSON); the page shows it in the reader's words
    expected: str  # as the scoring rule stated it (English); likewise
    measured: str
    backends: str
    tolerances: list[dict]
    verdict: str
    verdict_label: str
    score: float | None  # None while withheld from the student (verdict pending)
    points: float
    counted: bool
    feedback: str
    # An instructor's override (grader.services.submissions.overrides): {score, comment, by, at}, with the measured score beside it.
    override: dict | None = None
    measured_score: float | None = None
    # The runs this shown item reads whose measurements decide a withheld item: its evidence waits with them.
    evidence_withheld: list[str] = field(default_factory=list)

    @property
    def override_at(self) -> datetime | None:
        """When the override was set (stored in the report as UTC with its offset), naive UTC like every stored time."""
        return datetime.fromisoformat(self.override["at"]).replace(tzinfo=None) if self.override else None


@dataclass
class ConditionRow:
    id: str
    title: str
    passed: bool
    evidence: str


@dataclass
class CheckView:
    """The lab check stored with the grade: the L03 CHECK line and every condition with its evidence."""

    passed: bool
    verdict_line: str
    conditions: list[ConditionRow]
    rubric_version: str


@dataclass
class LaneRow:
    """One sliding cube of one friction run, from the run's stored metrics."""

    run: str
    lane: str
    table_friction: float
    cube_friction: float
    pair_friction: float | None
    stop: str
    max_tilt_deg: float | None
    tumbled: bool | None  # None: orientation not recorded (metrics stored before runner version 3)


@dataclass
class ReportView:
    submission: Submission
    runs: list[RunRow]
    grade: GradeView | None
    items: list[ItemRow] = field(default_factory=list)
    parts: list[tuple[str, list[ItemRow]]] = field(default_factory=list)
    config_findings: list[str] = field(default_factory=list)
    check: CheckView | None = None
    lanes: list[LaneRow] = field(default_factory=list)
    first_run_note: bool = False
    # Review requests about the items shown to the reader, oldest first, and every override ever set (staff read it).
    reviews: list[ReviewRequest] = field(default_factory=list)
    override_history: list[Override] = field(default_factory=list)
    # {case run: why} of the runs whose measurements decide an item withheld from the reader (GradeView.withheld_runs)
    withheld_runs: dict[str, str] = field(default_factory=dict)

    @property
    def some_withheld(self) -> bool:
        """Whether any item of the grade is withheld from the reader: then whether an instructor set its score is
        withheld with it, and the report may not say that every score is the measured one."""
        return self.grade is not None and bool(self.grade.hidden)

    @property
    def overridden(self) -> list[ItemRow]:
        return [i for i in self.items if i.override]

    @property
    def reviewable(self) -> list[ItemRow]:
        """The items a student may ask about now: shown to them, with no open request."""
        asked = {r.item_id for r in self.reviews if state_of(r) == "open"}
        return [i for i in self.items if i.verdict != "pending" and i.id not in asked]

    @property
    def tumbled_lanes(self) -> list[LaneRow]:
        return [lane for lane in self.lanes if lane.tumbled]

    @property
    def tumble_explanation(self) -> str:
        return TUMBLE_EXPLANATION

    @property
    def tumble_angle_deg(self) -> float:
        """The lesson cube's tip-over angle (a cube: width = height, so 45 degrees)."""
        return tumble_angle_deg(1.0, 1.0)

    @property
    def config_faults(self) -> list[str]:
        """The findings that broke the one-factor rule (rubric.one_factor's wording for a violation)."""
        return [f for f in self.config_findings if "too many inputs changed" in f]

    @property
    def completing(self) -> bool:
        """Graded, and the lab check of its grade is being evaluated (worker.grading.complete_grade)."""
        return self.grade is not None and self.grade.completed_at is None

    @property
    def finished(self) -> bool:
        return self.submission.status in (SubmissionState.GRADED, SubmissionState.FAILED) and not self.completing


def _elapsed(run: CaseRun, now: datetime) -> float | None:
    if run.started_at is None:
        return None
    return ((run.finished_at or now) - run.started_at).total_seconds()


def _files(run: CaseRun) -> list[str]:
    return evidence_names(run)  # from the database: the worker's folder may be on another host, or gone


def _tolerance_rows(names: dict[str, str], rubric) -> list[dict]:
    rows = []
    for name, value in names.items():
        record = rubric.tolerances.get(name) if rubric is not None else None
        rows.append({"name": name, "value": value, "rationale": record.rationale if record else "",
                     "reviewer": record.reviewer if record else "", "review_date": str(record.review_date) if record else ""})
    return rows


def _rubric(grade: Grade):
    """The grade's rubric version as the service stored it (shipped or published by an instructor). Read in the
    request's own session (a second one would hold a second pooled connection per request, and 50 readers at once
    exhausted the pool) and without parsing the shipped files on every page view."""

    try:
        return stored_version(object_session(grade), grade.rubric_lesson, grade.rubric_version, grade.rubric_hash)
    except Exception:  # a grade stays readable even if its rubric is unreadable: tolerances then show bare values
        return None


def report_view(submission: Submission, grade: GradeView | None,
                withheld: Mapping[str, str] | None = None) -> ReportView:
    """`grade`: the current grade as the reader may see it (grader.services.submissions.visibility), None when none is shown.
    `withheld`: {case run: why} of the runs whose measurements the reader may not see yet (GradeView.withheld_runs):
    listed with their state and why, without provenance, files or lanes."""
    now = utcnow()
    withheld = dict(withheld or {})
    runs = [RunRow(name=r.name, kind=r.kind, status=r.status, result_status=r.result_status, backend=r.backend,
                   # a withheld run keeps its state: its time, error and reuse would match it to another run
                   actual_backend=r.actual_backend, elapsed_s=None if r.name in withheld else _elapsed(r, now),
                   error=None if r.name in withheld else r.error,
                   reused_from_id=None if r.name in withheld else r.reused_from_id,
                   provenance={} if r.name in withheld else r.provenance or {},
                   files=[] if r.name in withheld else _files(r), withheld=withheld.get(r.name))
            for r in submission.case_runs]
    view = ReportView(submission=submission, runs=runs, grade=grade, withheld_runs=withheld,
                      lanes=_lanes([r for r in submission.case_runs if r.name not in withheld]))
    view.first_run_note = any(r.status == CaseRunState.RUNNING and (r.elapsed_s or 0) > FIRST_RUN_NOTE_AFTER_S for r in runs)
    if grade is None:
        return view
    report = grade.report
    rubric = _rubric(grade.stored)
    for item in report.get("items", []):
        override = item.get("override")  # never on a withheld item: grader.services.submissions.visibility masked it away
        counted = override is not None or item["verdict"] not in ("inconclusive", "pending")
        view.items.append(ItemRow(
            id=item["id"], part=item["part"], kind=item["kind"], question=item["question"],
            prediction=item["prediction"], expected=item["expected"], measured=item.get("measured", ""),
            backends=list(item.get("backends", {}).items()),  # (case, backend) pairs, worded by the template
            tolerances=_tolerance_rows(item.get("tolerances", {}), rubric), verdict=item["verdict"],
            # the measured verdict, overridden or not; the verdict cell links an override (_item_review.html)
            verdict_label=VERDICT_LABEL.get(item["verdict"], item["verdict"]),
            score=item["score"], points=item["points"], counted=counted, feedback=item["feedback"],
            override=override, measured_score=item.get("measured_score") if override else None,
            evidence_withheld=item.get("evidence_withheld", []),
        ))
    parts: dict[str, list[ItemRow]] = {}
    for row in view.items:
        parts.setdefault(row.part, []).append(row)
    view.parts = list(parts.items())
    view.config_findings = report.get("config_findings", [])
    view.check = _check(report.get("check"))
    _reviews(view, grade)
    return view


def _reviews(view: ReportView, grade: GradeView) -> None:
    """The requests and overrides beside a shown grade; a request about a withheld item waits until it is shown."""
    session = object_session(view.submission)
    requests = session.scalars(select(ReviewRequest).where(ReviewRequest.submission_id == view.submission.id)
                               .order_by(ReviewRequest.id))
    view.reviews = [r for r in requests if r.item_id not in grade.hidden]
    view.override_history = [] if grade.hidden else override_history(session, view.submission.id)


def _check(stored: dict | None) -> CheckView | None:
    """The stored check (rubric.check.CheckOutcome as JSON); None for grades stored before it was recorded."""
    if not stored:
        return None
    return CheckView(passed=stored["passed"], verdict_line=stored["verdict_line"],
                     rubric_version=stored["rubric_version"],
                     conditions=[ConditionRow(id=c["id"], title=c["title"], passed=c["passed"], evidence=c["evidence"])
                                 for c in stored["conditions"]])


def _lanes(runs: list[CaseRun]) -> list[LaneRow]:
    """Every lane of every friction run with stored metrics: its stop and whether it tumbled."""
    rows = []
    for run in runs:
        metrics = run.metrics or {}
        if metrics.get("kind") != "friction":
            continue
        for lane in metrics["lanes"].values():
            stop = lane["stop"]
            rows.append(LaneRow(
                run=run.name, lane=lane["lane"], table_friction=lane["table_friction"],
                cube_friction=lane["cube_friction"], pair_friction=lane["pair_friction"],
                stop=(f"{stop['distance']:.3f} m at t={stop['time']:.2f} s" if stop["stopped"] else stop["detail"]),
                max_tilt_deg=lane.get("max_tilt_deg"), tumbled=lane.get("tumbled"),
            ))
    return rows
