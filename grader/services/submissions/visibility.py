"""What a user may see of a grade: the one rule, used by the API, the pages and every export.

Staff (instructors and auditors of the course) see everything. A student sees an item's score and feedback at once
(immediate), from the due date that applies to them (after_due: their extension's where granted) or once the
assignment is released (on_release). Every submission of the lesson, to an assignment or outside any (a free one),
withholds whatever an assignment of its course for the lesson still withholds from that student, open or not yet
open: the same sheet sent to another assignment, or without `assignment_id`, must not tell what an assignment keeps
back. A withheld item keeps its question, points and
the student's own prediction; its score, verdict, evidence and feedback are not shown, the totals count the shown
items only, and the lab check waits until nothing is withheld.

An instructor's override (grader.services.submissions.overrides) is part of the stored grade's item (`override`, with the
measured score and verdict beside it), so it is shown exactly when its item is: a withheld item is masked down to its
question, points and prediction, and keeps neither the override's score nor its comment.

Withholding is per measurement, not only per item: the case runs whose measurements decide a withheld item are
withheld with it on every surface a student reads (`withheld_runs`): other items' evidence that reads them (with A2
withheld, X2's "penetration_proxy N1 ... -> extension ..." would answer A2), the report's charts and their series,
the runs' provenance, metrics and evidence downloads, and the lab check (left out while anything is withheld). Which
runs decide an item comes from the grade itself, as the rubric's scoring rules recorded it: the runs each item's rule
read (`backends`), for the items the rubric says are decided by measurement (kind `measured` or `computed`; a
`conceptual` or `config` item is decided by no run). A measured item that names no run read them all (the engine
version of every run's provenance), and before a grade exists every run is withheld while any item is.

Withholding of runs is per student and lesson, not per submission (issue 44, findings 5-A and 5-B): the lesson's runs
are the same for every sheet of a student, so every item of the lesson that any assignment of the course withholds
from the student (`lesson_withheld`, any part) withholds the runs that could tell its answer, on each of the
student's submissions of the lesson: the runs its scoring rule reads by declaration (the lesson's `runs_read`),
whatever the item's verdict (a hidden item graded one_factor_violation or not_measured still asks about them), and
whether or not the submission answers it (a checkpoint submission's lesson runs would answer an item of the
exercises). An item whose verdict reads a run of a withheld kind is withheld with them (`readers`, issue 44 hostile pass 6): H3 credited at B3's own tolerance
answered a withheld B3, and H4's credit on four stop distances bounded the withheld runs' values.

What a run measured, not its name, decides what it tells (issue 44): a run of the submission that measured the same as
a deciding run is withheld with it (`measurement_twins`): the same content key, measurement or evidence row (a reused
run), the same metrics but for the case's name, or bit-identical arrays. The colour-swapped control measures exactly
the baseline, and a sheet's table exercise at 0.30 exactly the lesson's friction-table-0.30; either would otherwise
answer a withheld item about the other under its own name.

Runs of one kind go further: a config can be built to measure what a withheld lesson run measured in more ways than
any rule over inputs or outputs lists (a nudged input, a shifted scene, bodies listed in another order), and another
lesson case of the kind tells the rule it shares (the friction cases' pair values tell the pair rule). While a run of
a case kind is withheld, every run of that kind is withheld with it (`withheld_runs`' `kinds`).
"""

from __future__ import annotations

import hashlib
import io
import json
import threading
import zipfile
from collections import OrderedDict
from collections.abc import Collection, Mapping, Sequence
from dataclasses import dataclass, field
from functools import cached_property
from datetime import datetime

import numpy as np
from sqlalchemy import select
from sqlalchemy.orm import Session, object_session

from grader.core.grades import current_grade
from grader.core.states import TERMINAL, CountedAttempt, Visibility
from grader.core.timezones import iso
from grader.core.models import Assignment, CaseEvidence, CaseRun, Grade, Submission, User, utcnow
from grader.services.setup.assignments import always_shown, counted_for, dates_for, item_ids, penalty_fraction
from grader.services.identity import access
from rubric import load_rubric
from rubric.lesson import lesson


def visibility_of(assignment: Assignment, item_id: str) -> str:
    """The item's own visibility where the assignment sets one, else the assignment's; a config item is always shown
    (`always_shown`: the sheet form's Check tells its answer before submitting, and which configs ran after)."""
    if item_id in always_shown(assignment.lesson):
        return Visibility.IMMEDIATE
    return (assignment.item_visibility or {}).get(item_id, assignment.visibility)


def withheld_items(*, session: Session, submission: Submission, user: User, now: datetime) -> dict[str, str]:
    """{item id: why `user` may not see its score and feedback yet}; empty for staff of the submission's course.
    A submission's items are withheld while any assignment of the course for its lesson withholds them from its
    student, its own assignment or another (issue 44: a practice assignment showing C1-C8 at once told what an exam
    withholding them until release keeps back), free submissions alike."""
    return _own_items(submission, lesson_withheld(session=session, submission=submission, user=user, now=now))


def _own_items(submission: Submission, lesson_hidden: dict[str, str]) -> dict[str, str]:
    """The part of `lesson_hidden` ({item id: why}, the lesson's) that is items of the submission."""
    ids = set(item_ids(submission.lesson, submission.part))
    return {i: why for i, why in lesson_hidden.items() if i in ids}


def _lesson_assignments(session: Session, submission: Submission) -> list[Assignment]:
    return list(session.scalars(select(Assignment).where(
        Assignment.course_id == submission.course_id, Assignment.lesson == submission.lesson).order_by(Assignment.id)))


def lesson_withheld(*, session: Session, submission: Submission, user: User, now: datetime) -> dict[str, str]:
    """{item id: why} of every item of the submission's lesson, in any part, that an assignment of its course
    withholds from its student at `now` (the submission's own assignment among them); empty for staff of the course.
    The runs that could tell these items' answers are withheld on every submission of the student for the lesson."""
    if access.is_staff(user) and user.course_id == submission.course_id:
        return {}
    hidden: dict[str, str] = {}
    for assignment in _lesson_assignments(session, submission):
        for i, reason in _withheld_by(session, assignment, submission.student, now).items():
            hidden.setdefault(i, reason)
    return hidden


def runs_answering(lesson_name: str, items: Collection[str], runs: Sequence[str]) -> dict[str, list[str]]:
    """{item id: the runs of `runs` that could tell its answer} for `items` of lesson `lesson_name`, as the lesson
    declares its scoring rules' reads (rubric.lesson.Lesson.runs_read); items reading none left out."""
    declared = lesson(lesson_name)
    out = {i: declared.runs_read(i, runs) for i in sorted(items)}
    return {i: names for i, names in out.items() if names}


def readers(lesson_name: str, items: Collection[str], runs: Sequence[str], kinds: Mapping[str, str]) -> dict[str, set[str]]:
    """{item id: the items of `items` it is withheld with}: every other item of lesson `lesson_name` whose verdict
    would tell a withheld item's answer (issue 44, hostile pass 6): one whose rule reads (the lesson's `runs_read`,
    over the submission's `runs`) a run of a case kind that a withheld item's runs are of, as the kind rule withholds
    every run of that kind. An item credited at a withheld item's own tolerance on the same runs answered it, and one
    credited on four stop distances bounded the withheld runs' values to 2 cm (docs/instructor.md gives the items).
    An item is withheld with them to keep their answers, not for its own: nothing is withheld for its sake in turn
    (the runs it reads stay as they were). A config item is never withheld (`always_shown`), so none asks here."""
    if not items:
        return {}
    declared = lesson(lesson_name)
    reads = {i.id: {kinds[r] for r in declared.runs_read(i.id, runs) if r in kinds}
             for i in load_rubric(lesson_name).items}
    held: dict[str, set[str]] = {}  # each withheld case kind, for which items
    for item in items:
        for kind in reads.get(item, ()):
            held.setdefault(kind, set()).add(item)
    out: dict[str, set[str]] = {}
    for item, kinds_read in reads.items():
        sources = set().union(*(held.get(k, set()) for k in kinds_read)) - {item}
        if item not in items and sources:
            out[item] = sources
    return out


def with_readers(lesson_name: str, hidden: Mapping[str, str], runs: Sequence[str],
                 kinds: Mapping[str, str]) -> dict[str, str]:
    """`hidden` ({item id: why}) and every item withheld with them (`readers`), saying with which."""
    out = dict(hidden)
    for item, sources in sorted(readers(lesson_name, hidden, runs, kinds).items()):
        why = "; ".join(sorted({hidden[s] for s in sources}))
        out[item] = f"{why} (its verdict reads the measurements that decide {', '.join(sorted(sources))})"
    return out


def withheld_by(*, session: Session, assignment: Assignment, student: User, now: datetime) -> dict[str, str]:
    """{item id: why} of the items of `assignment` it withholds from `student` at `now` (its due date as it applies to
    them, its release)."""
    return _withheld_by(session, assignment, student, now)


def _withheld_by(session: Session, assignment: Assignment, student: User, now: datetime) -> dict[str, str]:
    """{item id: why} of the items of `assignment` it withholds from `student` at `now`."""
    why: dict[str, str | None] = {Visibility.IMMEDIATE: None}
    ids = item_ids(assignment.lesson, assignment.part)
    kinds = {visibility_of(assignment, i) for i in ids}
    if Visibility.AFTER_DUE in kinds:
        due = dates_for(session=session, assignment=assignment, student=student).due_at
        why[Visibility.AFTER_DUE] = None if now >= due else (
            f"shown after the due date, {iso(due, assignment.course.timezone)}")
    if Visibility.ON_RELEASE in kinds:
        why[Visibility.ON_RELEASE] = None if assignment.released_at is not None else (
            f"shown once “{assignment.title}” is released by an instructor")
    hidden = {i: why[visibility_of(assignment, i)] for i in ids}
    return {i: reason for i, reason in hidden.items() if reason}


def next_shown_at(*, session: Session, submission: Submission, user: User, now: datetime) -> datetime | None:
    """The next instant after `now` at which time alone shows `user` an item of `submission` withheld at `now` (a due
    date passing, the student's extension's where granted), or None where no such instant comes: releases and every
    other change are writes. What a validator kept in memory must not outlive (grader.web.fresh). Every assignment of
the lesson counts, not only the submission's own: its due date can show an item whose runs this submission withholds."""
    if access.is_staff(user) and user.course_id == submission.course_id:
        return None
    times = []  # every assignment of the lesson: each one's withheld items withhold runs here (`lesson_withheld`)
    for assignment in _lesson_assignments(session, submission):
        if any(visibility_of(assignment, i) == Visibility.AFTER_DUE for i in item_ids(assignment.lesson, assignment.part)):
            due = dates_for(session=session, assignment=assignment, student=submission.student).due_at
            if due > now:
                times.append(due)
    return min(times, default=None)


# Items the rubric decides by measurement (rubric.rubrics.ItemKind); a conceptual item's runs only illustrate it and
# a config item is decided from the submitted configs.
MEASURED_KINDS = ("measured", "computed")
NOT_DECIDED = ("not_measured", "one_factor_violation")  # no measurement decided these verdicts


def deciding_runs(item: dict, runs: list[str]) -> list[str]:
    """The case runs whose measurements decide a stored report item: the runs its scoring rule read (`backends`, by
    the names the grade gives them) where the rubric decides it by measurement; every one of `runs` (the submission's)
    where such an item names none (its rule read every run, as the engine version does); none for a conceptual or
    config item, or a verdict no measurement decided."""
    if item.get("kind") not in MEASURED_KINDS or item.get("verdict") in NOT_DECIDED:
        return []
    return list(item.get("backends") or {}) or list(runs)


def withheld_runs(report: dict | None, hidden: dict[str, str], runs: list[str],
                  twins: Mapping[str, Collection[str]] | None = None,
                  asked: Mapping[str, tuple[str, Collection[str]]] | None = None,
                  kinds: Mapping[str, str] | None = None) -> dict[str, str]:
    """{case run name: why its measurements are withheld}: the runs deciding any withheld item of `report` (the
    stored grade's), the runs that could tell the answer of any item of `asked` ({item id: (why it is withheld, those
    runs)}: every item of the lesson withheld from the student, `lesson_withheld` and `runs_answering`), each with the
    items it decides and when they are shown, and each run of `twins` ({run: the runs that measured the same},
    `measurement_twins`) of such a run, which would tell the same; and every run of the kind of a withheld run
    (`kinds`: {run name: its case kind}): a run of one kind tells another's physics in more ways than a rule over
    inputs or outputs lists (a config nudged below single precision, a shifted scene, bodies listed in another order;
    another lesson case read for the rule it shares, as the friction cases' pair values tell the pair rule). Without a report (not graded yet) every run is withheld while
    any item of the submission is: nothing yet says which run decided which item."""
    asked = asked or {}
    if not hidden and not asked:
        return {}
    if report is None and hidden:
        why = "; ".join(sorted(set(hidden.values())))
        return {r: f"decides withheld items ({', '.join(sorted(hidden))}), {why}" for r in runs}
    decides: dict[str, set[str]] = {}
    whys = {i: why for i, (why, _) in asked.items()} | hidden
    for item in (report or {}).get("items", []):
        if item["id"] in hidden:
            for run in deciding_runs(item, runs):
                decides.setdefault(run, set()).add(item["id"])
    for item_id, (_, names) in asked.items():
        for run in names:
            if run in runs:
                decides.setdefault(run, set()).add(item_id)
    out = {run: f"decides {', '.join(sorted(ids))}, " + "; ".join(sorted({whys[i] for i in ids}))
           for run, ids in sorted(decides.items())}
    deciding = sorted(out)
    kinds = kinds or {}
    # A twin and a run of a withheld kind say the same: which kind of run it is and which deciding run of the kind it
    # is withheld with. "measured the same as" would tell that two withheld runs measured alike (the colour-swapped
    # control and the baseline: C7's and B4's answer), issue 44 hostile pass 8.
    withheld_with: dict[str, str] = {}
    for run in deciding:  # sorted: a twin of two deciding runs is named after the first
        for twin in sorted((twins or {}).get(run, ())):
            withheld_with.setdefault(twin, run)
    for run, kind in sorted(kinds.items()):
        like = next((other for other in deciding if kinds.get(other) == kind and other != run), None)
        if like is not None:
            withheld_with.setdefault(run, like)
    for run, source in sorted(withheld_with.items()):
        if run in out:
            continue
        kind = kinds.get(run)
        like = next((other for other in deciding if kind is not None and kinds.get(other) == kind), source)
        out[run] = (f"is a {kind} run, as {like} is, which {out[like]}" if kind is not None
                    else f"is withheld with {like}, which {out[like]}")
    return out


def _without_names(value):
    """Stored metrics without the case's name (`case`, at the top and in each lane): what the run measured."""
    if isinstance(value, dict):
        return {k: _without_names(v) for k, v in value.items() if k != "case"}
    if isinstance(value, list):
        return [_without_names(v) for v in value]
    return value


# What each stored .npz holds, digested once per process by (evidence row, when it was stored): a student's report,
# series and files each ask which runs measured alike while an item is withheld, and the archives are tens of kB. A row
# stored again (a re-sent run's new try) has a new stored_at, so a stale digest is never read.
_DIGESTS: OrderedDict[tuple[int, datetime], str] = OrderedDict()
_DIGESTS_LOCK = threading.Lock()  # an API process serves reads on many threads
DIGESTS_CACHED = 1024


def _arrays_digest(session: Session, row: int, stored_at: datetime) -> str | None:
    """sha256 of what an evidence row's .npz measured: each sampled array's name, dtype, shape and bytes, by name,
    leaving out the time axis `t` and the 0-d arrays (the scalars a run records of its inputs, such as the friction
    the engine held). A config nudged below float32's resolution (table friction 0.5000000001) integrates bit for bit
    as the baseline, with its own `t` and input scalars: the same measurement. Not the archive's bytes, which also
    hold each entry's time. None for a row without arrays."""
    with _DIGESTS_LOCK:
        if (found := _DIGESTS.get((row, stored_at))) is not None:
            _DIGESTS.move_to_end((row, stored_at))
            return found
    blob = session.scalar(select(CaseEvidence.arrays).where(CaseEvidence.case_run_id == row))
    if not blob:
        return None
    digest = hashlib.sha256()
    try:
        with np.load(io.BytesIO(blob), allow_pickle=False) as arrays:
            for name in sorted(arrays.files):
                array = arrays[name]
                if name == "t" or array.ndim == 0:
                    continue
                digest.update(f"{name}\0{array.dtype.str}\0{array.shape}\0".encode())
                digest.update(np.ascontiguousarray(array).tobytes())
    except (ValueError, OSError, zipfile.BadZipFile):  # not arrays a case process writes: alike to nothing
        return None
    with _DIGESTS_LOCK:
        _DIGESTS[(row, stored_at)] = digest.hexdigest()
        while len(_DIGESTS) > DIGESTS_CACHED:
            _DIGESTS.popitem(last=False)
    return digest.hexdigest()


def measurement_twins(runs: Sequence[CaseRun]) -> dict[str, list[str]]:
    """{run name: the other runs of `runs` that measured the same}, for the runs that have any: one content key,
    measurement or evidence row (a reused run reads its source's), equal metrics but for the case's name, arrays
    equal bit for bit, or one physics however sampled, labelled or run (the lesson's `physics_key`: a student's
    extension at dt 0.02 with 4 substeps measured N2 bit for bit at every other sample, and told A2's withheld N2
    proxy); closed under "the same as" (a run alike to a twin is one too). Arrays are read only where two
    runs' stored .npz have one size, and digested once per process (`_arrays_digest`)."""
    finished = {r.name: r.reused_from_id or r.id for r in runs if r.status in TERMINAL}  # its evidence row
    declared = lesson(runs[0].submission.lesson) if runs else None
    groups: dict[tuple, set[str]] = {}
    for run in runs:
        marks = [("key", run.content_key), ("measurement", run.measurement_id), ("evidence", finished.get(run.name)),
                 ("metrics", json.dumps(_without_names(run.metrics), sort_keys=True) if run.metrics else None),
                 ("physics", declared.physics_key(run.kind, run.spec) if declared else None)]
        for mark in marks:
            if mark[1] is not None:
                groups.setdefault(mark, set()).add(run.name)
    session = object_session(runs[0]) if runs else None
    if session is not None and len(set(finished.values())) > 1:
        stored = session.execute(select(CaseEvidence.case_run_id, CaseEvidence.sizes, CaseEvidence.stored_at)
                                 .where(CaseEvidence.case_run_id.in_(set(finished.values())))).all()
        by_size: dict[int, list[tuple[int, datetime]]] = {}
        for row, sizes, stored_at in stored:
            if size := (sizes or {}).get("arrays.npz"):
                by_size.setdefault(size, []).append((row, stored_at))
        digests = {row: _arrays_digest(session, row, at)
                   for rows in by_size.values() if len(rows) > 1 for row, at in rows}
        for name, row in finished.items():
            if digests.get(row) is not None:
                groups.setdefault(("arrays", digests[row]), set()).add(name)
    alike = {r.name: {r.name} for r in runs}
    for names in groups.values():  # merge every group sharing a run with this one, until none is left to merge
        merged = set(names).union(*(alike[n] for n in names))
        for name in merged:
            alike[name] = merged
    return {name: sorted(others - {name}) for name, others in alike.items() if len(others) > 1}


def _evidence_withheld(item: dict, runs: dict[str, str]) -> dict:
    """A shown item whose rule read a withheld run: its score and verdict stay, the measured values (its evidence,
    what was measured and, for a measured item, the expected answer derived from them) wait with the run."""
    names = [r for r in item.get("backends") or {} if r in runs]
    masked = {"measured": "", "evidence": None, "evidence_withheld": names,
              "feedback": (f"Verdict: {item['verdict'].replace('_', ' ')}. Evidence withheld: it reads the measurements "
                           f"of {', '.join(names)}: " + "; ".join(f"{n} {runs[n]}" for n in names) + ".")}
    if item.get("kind") in MEASURED_KINDS:
        masked["expected"] = ""
    return item | masked


def shown_report(report: dict, hidden: dict[str, str], runs: list[str] | None = None,
                 twins: Mapping[str, Collection[str]] | None = None,
                 asked: Mapping[str, tuple[str, Collection[str]]] | None = None,
                 kinds: Mapping[str, str] | None = None, deciding: Mapping[str, str] | None = None) -> dict:
    """The stored report as a student may see it: each withheld item keeps its question, points and the student's
    own prediction, but its score is None and its feedback says when it will be shown; the total counts the shown
    items only and `pending` says which points are still to come. The lab check (its conditions' evidence is
    measured against the same tolerances) is left out until nothing is withheld. Nothing is regraded on release.
    `twins`: the runs that measured the same as each run (`measurement_twins`), withheld with a deciding one; `asked`:
    the lesson's items withheld from the student and the runs that could answer them (`withheld_runs`)."""
    # `deciding`: the withheld items whose runs are withheld with them (default every one); an item withheld only
    # because its verdict would tell one of them (`readers`) withholds no run of its own
    withheld = withheld_runs(report, hidden if deciding is None else deciding,
                             runs if runs is not None else _read_runs(report), twins, asked, kinds)
    if not hidden and not withheld:
        return report
    items, total, shown_max, pending_points = [], 0.0, 0.0, 0.0
    for item in report.get("items", []):
        if item["id"] not in hidden and set(item.get("backends") or {}) & set(withheld):
            item = _evidence_withheld(item, withheld)
        if item["id"] in hidden:
            pending_points += item["points"]  # its worth, not max_score: that would tell an inconclusive one apart
            items.append({k: item[k] for k in ("id", "part", "kind", "question", "prediction", "points")}
                         | {"score": None, "max_score": item["points"], "verdict": "pending", "expected": "",
                            "measured": "", "evidence": None, "tolerances": {}, "backends": {},
                            "feedback": f"withheld: {hidden[item['id']]}"})
        else:
            total, shown_max = total + item["score"], shown_max + item["max_score"]
            items.append(item)
    names = [i["id"] for i in items if i["id"] in hidden]
    max_total = shown_max + pending_points
    note = (f"{pending_points:g} of {max_total:g} points pending ({', '.join(names)}): "
            + "; ".join(sorted(set(hidden.values())))) if hidden else None
    # which item the grade's last override changed would tell a withheld one was overridden: left out while any is;
    # so are the engine version its runs recorded and whether every item was measured (the answer of a withheld H6,
    # a withheld item's state), and the one-factor findings while a config item is withheld (they are its answer)
    dropped = {"made_by_override", "engine_version", "complete"}
    if any(i.get("kind") == "config" and i["id"] in hidden for i in report.get("items", [])):
        dropped.add("config_findings")
    kept = {k: v for k, v in report.items() if k not in dropped}
    return {**kept, "items": items, "total": round(total, 6), "max_total": max_total, "pending": note,
            "check": None, "withheld_measurements": withheld}


def _read_runs(report: dict) -> list[str]:
    """Every run the report's items name (a report read without its submission's runs at hand)."""
    return sorted({r for item in report.get("items", []) for r in item.get("backends") or {}})


@dataclass(frozen=True)
class GradeView:
    """The current grade of a submission as one user may see it now.

    `stored` is the grade row (None before grading); read the scores through this view, never through `stored`,
    unless `hidden` is empty. `nothing_shown` says why no score at all may be shown (every item withheld)."""

    submission: Submission
    stored: Grade | None
    # the submission's items withheld from the user: for their own answers (`deciding`) or because their verdicts
    # would tell one of those (`readers`)
    hidden: dict[str, str] = field(default_factory=dict)
    # every item of the lesson withheld from the submission's student, in any assignment (`lesson_withheld`): the
    # runs that could answer them are withheld here too
    lesson_hidden: dict[str, str] = field(default_factory=dict)

    @property
    def item_count(self) -> int:
        return len(item_ids(self.submission.lesson, self.submission.part))

    @property
    def nothing_shown(self) -> str | None:
        if not self.hidden or len(self.hidden) < self.item_count:
            return None
        return "scores and feedback are " + " and ".join(sorted(set(self.hidden.values())))

    @property
    def some_withheld(self) -> str | None:
        """Why some item is withheld (the grade history's totals would tell it), or None."""
        return ("some items' scores and feedback are " + " and ".join(sorted(set(self.hidden.values())))
                if self.hidden else None)

    @property
    def shown(self) -> bool:
        """Whether there is a grade and any of it may be shown."""
        return self.stored is not None and self.nothing_shown is None

    @cached_property  # masked once per view: total, max_total and pending all read it
    def report(self) -> dict | None:
        """The report as this user may see it (the stored one where nothing is withheld)."""
        if not self.shown:
            return None
        if not self.hidden and not self.lesson_hidden:
            return self.stored.report
        return shown_report(self.stored.report, self.hidden, self.run_names, self.twins, self.asked, self.kinds,
                            self.deciding)

    @cached_property
    def asked(self) -> dict[str, tuple[str, list[str]]]:
        """{item id: (why it is withheld, the submission's runs that could answer it)} for the lesson's items withheld
        from the student (`lesson_withheld`, `runs_answering`)."""
        if not self.lesson_hidden:
            return {}
        answering = runs_answering(self.submission.lesson, self.lesson_hidden, self.run_names)
        return {i: (self.lesson_hidden[i], names) for i, names in answering.items()}

    @property
    def deciding(self) -> dict[str, str]:
        """The submission's withheld items withheld for their own answers (not only as `readers` of another's): the
        runs that decide them are withheld with them."""
        return {i: why for i, why in self.hidden.items() if i in self.lesson_hidden}

    @property
    def run_names(self) -> list[str]:
        return [r.name for r in self.submission.case_runs]

    @property
    def kinds(self) -> dict[str, str]:
        return {r.name: r.kind for r in self.submission.case_runs}

    @cached_property
    def twins(self) -> dict[str, list[str]]:
        """{run name: the submission's other runs that measured the same} (`measurement_twins`); read only while
        something is withheld."""
        return measurement_twins(self.submission.case_runs) if self.hidden or self.lesson_hidden else {}

    @cached_property
    def withheld_runs(self) -> dict[str, str]:
        """{case run name: why} of the runs whose measurements this user may not see yet (see `withheld_runs`):
        their series, metrics, provenance and evidence files, and those of every run that measured the same. A
        function of `hidden`, the stored grade and the submission's runs (their states and deliveries say when what
        they measured changes), which the report's validator (grader.web.etag.report_state) already covers."""
        if not self.hidden and not self.lesson_hidden:
            return {}
        return withheld_runs(self.stored.report if self.stored is not None else None, self.deciding, self.run_names,
                             self.twins, self.asked, self.kinds)

    @property
    def total(self) -> float | None:
        if not self.shown:
            return None
        return self.report["total"] if self.hidden else self.stored.total

    @property
    def max_total(self) -> float | None:
        if not self.shown:
            return None
        return self.report["max_total"] if self.hidden else self.stored.max_total

    @property
    def pending(self) -> str | None:
        return self.report.get("pending") if self.shown and self.hidden else None

    # The stored grade's provenance, never withheld: which rubric, and whether its lab check is stored.
    @property
    def rubric_lesson(self) -> str | None:
        return self.stored.rubric_lesson if self.stored is not None else None

    @property
    def rubric_version(self) -> str | None:
        return self.stored.rubric_version if self.stored is not None else None

    @property
    def completed_at(self) -> datetime | None:
        return self.stored.completed_at if self.stored is not None else None


def grade_view(*, session: Session, submission: Submission, user: User, now: datetime | None = None,
               report: bool = True) -> GradeView:
    """The current grade of `submission` as `user` may see it at `now` (default: now).

    `report=False` defers the grade's report (the largest JSON) until a withheld item needs it masked."""
    lesson_hidden = lesson_withheld(session=session, submission=submission, user=user, now=now or utcnow())
    shown_with = lesson_hidden
    if lesson_hidden:  # and every item whose verdict would tell one of them (`readers`)
        runs = submission.case_runs
        shown_with = with_readers(submission.lesson, lesson_hidden, [r.name for r in runs],
                                  {r.name: r.kind for r in runs})
    return GradeView(submission=submission, stored=current_grade(session, submission.id, report=report),
                     hidden=_own_items(submission, shown_with), lesson_hidden=lesson_hidden)


def attempt_standing(session: Session, submission: Submission, user: User, view: GradeView | None = None) -> dict:
    """What `user` may see of an assignment attempt's standing: the late penalty (it follows from the lateness alone:
    never withheld), the raw and counted score (only with the whole grade shown) and whether it is the attempt that
    counts (withheld under "best" while any item is: it would tell a hidden score)."""
    out: dict = {"penalty": None, "raw_score": None, "counted_score": None, "counts": None}
    assignment = submission.assignment
    if assignment is None:
        return out
    view = view or grade_view(session=session, submission=submission, user=user, report=False)
    out["penalty"] = penalty_fraction(assignment, submission.late_seconds or 0)
    if view.stored is not None:
        mine, counting_id = counted_for(session=session, submission=submission)
        if mine is not None and not view.hidden:
            out |= {"raw_score": mine.raw, "counted_score": mine.counted}
        if not view.hidden or assignment.counted_attempt == CountedAttempt.LATEST:
            out["counts"] = counting_id == submission.id
    return out
