"""Case-run and submission state in the database: claim, store a measured or reused result, finish, grade once.

The neutral core shared by the API and the worker: plain functions on a session, no Celery, no case process, no
engine. worker.case_run decides what to do with a claimed run and worker.grading grades; this module records it
with its evidence (CaseEvidence: the case folder is only a cache), and reads a stored result back from the database
(`stored_result`) for grading, the lab check, the regrade, the audit and the report's charts.
"""

from __future__ import annotations

import io
import json
import os
import socket
import threading
from collections import OrderedDict
from datetime import datetime, timedelta
from pathlib import Path
from typing import Any

import numpy as np
from sqlalchemy import func, null, select, update
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session, object_session

from rubric import CaseResult, Provenance, parse_case
from rubric.lesson import parse_metrics

from grader.core.models import CaseEvidence, CaseRun, Event, Grade, Measurement, Submission, utcnow
from grader.core.settings import settings
from grader.core import content_key
from grader.core.states import TERMINAL, CaseRunPurpose, CaseRunState, SubmissionState

HOST = socket.gethostname()
# The files of a case run's evidence (CaseEvidence), by the names a case process writes and a download serves.
EVIDENCE_FILES = ("arrays.npz", "provenance.json", "metrics.json", "spec.json", "stdout.txt", "stderr.txt")
# Where a message goes in its queue (kombu's Redis and filesystem transports serve the lowest number first): a run whose worker died mid-case first, then a queued run whose message was
# lost (a broker restart), then new runs, and last the lab check of a grade already stored (it goes on the cpu
# queue too, so a worker evaluates it only when no case waits: at a deadline every grade comes first).
RERUN_PRIORITY, REQUEUED_PRIORITY, NEW_PRIORITY, COMPLETE_PRIORITY = 0, 3, 6, 9
# A variant pool's measuring runs (grader.services.setup.variants), sent and re-sent: the lowest, behind every student's
# runs (a student's next run waits at most for the pool runs slots already hold), in order sent with the lab checks.
POOL_PRIORITY = 9
# A pool's lab check (the completion of a measuring submission's grade, which keeps or drops its variant): ahead of
# every pool's runs, so a pool whose runs are done (or reused) is decided without waiting behind another pool's runs
# (issue 47: 9 minutes behind one here), and behind a student's first runs. It takes a fraction of a second.
POOL_CHECK_PRIORITY = 8
# A student's new runs take 4, 5, 6, 7, then 8 for the rest, by how many of that student's runs wait ahead of them
# (worker.celery_app gives Redis one list per priority 0-9): a student with one run waiting is served before the
# fourth run of a student who queued nine, so students' runs interleave instead of first come, first served.
FAIR_PRIORITIES = (4, 5, 6, 7, 8)


def fair_priority(waiting_ahead: int) -> int:
    """The priority of a student's new run with `waiting_ahead` of their own runs already waiting in its queue."""
    return FAIR_PRIORITIES[min(waiting_ahead, len(FAIR_PRIORITIES) - 1)]


def _pid_alive(pid: int | None) -> bool:
    if not pid:
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return not _zombie(pid)


def _zombie(pid: int) -> bool:
    """A killed process nobody has reaped yet still answers signal 0: dead all the same. (Seen when a worker's whole
    process tree was SIGKILLed and a new worker started on the same host within a second: its orphans were not yet
    reaped by init, so the run they held looked alive and waited for the broker's redelivery, 13 minutes.)"""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:  # no /proc (not Linux) or gone meanwhile
        return False
    return stat.rsplit(")", 1)[-1].split()[0] in ("Z", "X")


def held_by_the_dead(run: CaseRun) -> bool:
    """The run is held by a process of this host that no longer exists (a killed worker's run, before its lease ends).
    False for a run held on another host: only its lease tells there."""
    return run.worker == HOST and not _pid_alive(run.worker_pid)


def dead_here(session: Session) -> list[CaseRun]:
    """Running runs claimed on this very host by a process that no longer exists (locked; knowable without a broker).

    No grace: a claim records its live pid in the same transaction, so a dead pid is certain, never in transit."""
    running = select(CaseRun).where(CaseRun.status == CaseRunState.RUNNING, CaseRun.worker == HOST)
    return [run for run in session.scalars(running.with_for_update(skip_locked=True)).all()
            if held_by_the_dead(run)]


def lease_expired(now: datetime):
    """SQL: a running run whose lease ran out (its worker crashed, or its host was lost)."""
    return (CaseRun.status == CaseRunState.RUNNING) & (CaseRun.lease_until < now)


def queue_lease_expired(now: datetime):
    """SQL: a queued run no worker took within the queue lease (its message presumed lost)."""
    return (CaseRun.status == CaseRunState.QUEUED) & (CaseRun.queued_at < now - timedelta(seconds=settings.queue_lease_s))


def stuck_reason(run: CaseRun, now: datetime) -> str | None:
    """Why an unfinished run looks stuck, or None: the rule of `lease_expired` and `queue_lease_expired`, for a row."""
    if run.status == CaseRunState.RUNNING and run.lease_until is not None and run.lease_until < now:
        return f"running past its lease (since {run.lease_until:%H:%M:%S} UTC) on {run.worker or 'an unknown worker'}"
    if run.status == CaseRunState.QUEUED and run.queued_at < now - timedelta(seconds=settings.queue_lease_s):
        return f"queued for more than {settings.queue_lease_s:.0f} s"
    return None


def requeue(session: Session, run: CaseRun, reason: str) -> None:
    """Back to queued under a new delivery number, which makes every older message for it stale; the caller sends it.

    For the reconciler and a worker starting where one died: the run keeps its tries (bounded by max_infra_retries)."""
    run.status, run.delivery, run.queued_at = CaseRunState.QUEUED, run.delivery + 1, utcnow()
    run.worker = run.worker_pid = run.lease_until = None
    session.add(Event(submission_id=run.submission_id, case_run_id=run.id, state="requeued",
                      detail=f"{reason}; delivery {run.delivery} on queue {run.backend}"))


def resend(session: Session, run: CaseRun, *, by: str) -> None:
    """A person re-sends a failed or stuck run (`by`: "instructor NAME"): queued under a new delivery number with its
    tries, result and evidence cleared as before its first run, recorded in an event that keeps the old error. A grade
    that counted the run is superseded (kept in the history) and the submission is graded again once the run
    finishes; a failed submission goes back to running. The caller has locked the submission and commits."""
    submission, now = run.submission, utcnow()
    was = run.status
    previous = run.error if was == CaseRunState.FAILED else stuck_reason(run, now)
    old = f"delivery {run.delivery}, try {run.tries}" + (f", evidence in {run.artifact_dir}" if run.artifact_dir else "")
    run.status, run.delivery, run.tries, run.queued_at = CaseRunState.QUEUED, run.delivery + 1, 0, now
    run.worker = run.worker_pid = run.lease_until = run.started_at = run.finished_at = None
    run.result_status = run.error = run.stderr_tail = run.wall_s = run.actual_backend = None
    run.artifact_dir = run.measurement_id = run.reused_from_id = None
    run.provenance = run.metrics = null()  # SQL NULL, as before the first run (None would store JSON 'null')
    session.add(Event(submission_id=submission.id, case_run_id=run.id, state="resent",
                      detail=f"resent by {by}: was {was} ({old}): {previous}; "
                             f"delivery {run.delivery} on queue {run.backend}"))
    grade = session.scalar(select(Grade).where(Grade.submission_id == submission.id, Grade.superseded_at.is_(None)))
    if grade is not None:
        # The grade that counted this run as not measured is kept in the history, superseded; the submission is
        # graded again, under the course's version, once the re-sent run finishes (one current grade at a time).
        grade.superseded_at = now
        submission.status, submission.updated_at = SubmissionState.RUNNING, now
        session.add(Event(submission_id=submission.id, state=SubmissionState.RUNNING,
                          detail=f"case run {run.name} resent by {by}: the grade under v{grade.rubric_version} is "
                                 "kept in the history, superseded; graded again when the run finishes"))
    elif submission.status == SubmissionState.FAILED:
        previous_error = submission.error
        submission.status, submission.error, submission.updated_at = SubmissionState.RUNNING, None, now
        session.add(Event(submission_id=submission.id, state=SubmissionState.RUNNING,
                          detail=f"case run {run.name} resent by {by}; was failed: {previous_error}"))


def lock_submission(session: Session, submission_id: int) -> None:
    """Lock a submission's row: its finishers (`_finish`) and a resend serialize, so exactly one sees the last run
    done. Take it before a case run's lock (the order `_finish` takes).

    FOR NO KEY UPDATE (PostgreSQL; SQLite serializes writers anyway): it excludes another finisher as FOR UPDATE does,
    but not the key-share lock an insert of a row referencing the submission takes (an event, a grade). Two case runs
    of one submission finishing at once on two slots deadlocked under FOR UPDATE ("while locking tuple in relation
    submissions"): each transaction's key-share lock blocked the other's upgrade."""
    session.execute(select(Submission.id).where(Submission.id == submission_id).with_for_update(key_share=True))


def release(session: Session, case_run_id: int, delivery: int, reason: str) -> bool:
    """A run this process claimed and could not finish because the database or the broker failed mid-way: back to
    queued under the same delivery, so the task's own retry claims it again on whichever pool process takes it (its
    tries count it). Without this, a retry on a sibling process found the run held by a live process and dropped it,
    leaving it running until the reconciler or its lease. False (nothing changed) when the run is not this process's
    claim of this delivery. The caller commits."""
    run = session.get(CaseRun, case_run_id, with_for_update=True)
    if (run is None or run.delivery != delivery or run.status != CaseRunState.RUNNING or run.worker != HOST
            or run.worker_pid != os.getpid()):
        return False
    run.status, run.queued_at = CaseRunState.QUEUED, utcnow()
    run.worker = run.worker_pid = run.lease_until = None
    session.add(Event(submission_id=run.submission_id, case_run_id=run.id, state="released",
                      detail=f"{reason}; queued again for the task's retry, delivery {run.delivery}"))
    return True


def claim(*, session: Session, case_run_id: int, delivery: int) -> tuple[CaseRun | None, bool]:
    """(run, False) when the run is now ours; (None, started_grading) when this delivery must not run it.

    Stale deliveries (finished, superseded delivery, held by a live worker) are dropped.

    A redelivery of the same delivery number may take over a running case run when the process that held it is dead
    (same host) or its lease has expired; every take-over counts in `tries`, which is bounded.
    """
    run = session.get(CaseRun, case_run_id, with_for_update=True)
    if run is None or run.delivery != delivery or run.status in TERMINAL:
        return None, False
    now = utcnow()
    if run.status == CaseRunState.RUNNING:
        ours = run.worker == HOST and (run.worker_pid == os.getpid() or not _pid_alive(run.worker_pid))
        if not ours and run.lease_until and run.lease_until > now:
            return None, False
    if run.tries >= settings.max_infra_retries + 1:
        error = f"gave up after {run.tries} deliveries lost to worker failures"
        return None, _finish(session, run, status=CaseRunState.FAILED, error=error)
    run.status, run.tries = CaseRunState.RUNNING, run.tries + 1
    run.worker, run.worker_pid = HOST, os.getpid()
    run.started_at, run.lease_until = now, now + timedelta(seconds=settings.lease_s)
    session.add(Event(submission_id=run.submission_id, case_run_id=run.id, state=CaseRunState.RUNNING,
                      detail=f"{HOST} pid {os.getpid()} try {run.tries}"))
    return run, False


def _apply_measurement(run: CaseRun, measurement: Measurement) -> str:
    """Point the run at a stored measurement of its content key: its evidence, metrics and backend become the run's.
    Returns the event text that says so."""
    run.content_key = measurement.content_key
    run.measurement_id, run.reused_from_id = measurement.id, measurement.case_run_id
    run.provenance, run.artifact_dir = measurement.provenance, measurement.artifact_dir
    run.metrics = measurement.metrics
    run.actual_backend, run.result_status = measurement.backend, "ok"
    return f"reused measurement {measurement.id} of case run {measurement.case_run_id}"


def store_reused(*, session: Session, run: CaseRun, measurement: Measurement) -> bool:
    """Finish the run on a stored measurement of the same content key; True when this moved it to grading."""
    return _finish(session, run, status=CaseRunState.DONE, detail=_apply_measurement(run, measurement))


# The end of the event detail of a run that finish_alike finished (tools/bench counts them by it).
FINISHED_WHEN_MEASURED = "(finished when it was measured)"


def finish_alike(session: Session, case_run_id: int) -> list[int]:
    """Once a run has stored a new measurement, finish on it every queued grading run of the same content key, before
    any of their messages reaches a worker (a worker then drops each message as finished, `claim`). A class at the
    deadline queues the same case for many sheets; without this each of those runs took a case slot in turn, only to
    find the measurement and reuse it. Returns the submissions this moved to grading: their grade tasks are the
    caller's to send.

    Candidates share the run's spec_key, backend and precision; each is reused only when the content key of its own
    spec, computed here where the case ran, is the measurement's. One transaction per run, its submission locked first
    (the order `_finish` takes), so a worker claiming one of them meanwhile either finds it finished or keeps it."""
    run = session.get(CaseRun, case_run_id)
    if (run is None or run.status != CaseRunState.DONE or run.purpose != CaseRunPurpose.GRADING
            or run.reused_from_id is not None or run.measurement_id is None or run.spec_key is None):
        return []
    backend, precision = run.backend, run.precision
    measurement = session.get(Measurement, run.measurement_id)
    session.expunge(measurement)  # read once: the commits below would expire it and reload it for every run
    key = measurement.content_key
    candidates = session.execute(
        select(CaseRun.id, CaseRun.submission_id, CaseRun.spec).join(Submission, Submission.id == CaseRun.submission_id)
        .where(CaseRun.spec_key == run.spec_key, CaseRun.backend == backend, CaseRun.precision == precision,
               CaseRun.status == CaseRunState.QUEUED, CaseRun.purpose == CaseRunPurpose.GRADING,
               Submission.force_rerun.is_(False))
        .order_by(CaseRun.submission_id, CaseRun.id)).all()
    session.rollback()  # no transaction held across the runs below
    moved = []
    for other_id, submission_id, spec in candidates:
        if content_key.content_key(content_key.key_inputs(spec, backend=backend, precision=precision)) != key:
            continue
        lock_submission(session, submission_id)
        other = session.get(CaseRun, other_id, with_for_update=True, populate_existing=True)
        if other.status != CaseRunState.QUEUED:  # a worker claimed it meanwhile: it reuses the measurement itself
            session.rollback()
            continue
        detail = _apply_measurement(other, measurement)
        if _finish(session, other, status=CaseRunState.DONE, detail=f"{detail} {FINISHED_WHEN_MEASURED}"):
            moved.append(submission_id)
    return moved


def reuse_at_admission(*, session: Session, submission: Submission) -> bool:
    """Finish each queued case run of a new submission whose content key already has a stored measurement, in the
    request that stores it (no commit here: the caller's one transaction holds the submission and its runs). True when
    none is left to run, the submission then 'grading': only its grade task needs sending. The worker decides again
    for each run it receives (worker.case_run.reusable), so this only spares a broker round trip per stored case.

    The key is grader.core.content_key's, computed with the engine versions installed beside the API: a host whose versions
    differ from the measurement's finds no key and queues the run, which the worker then measures or reuses."""
    if submission.force_rerun:
        return False
    for run in submission.case_runs:
        if run.status != CaseRunState.QUEUED:
            continue
        key = content_key.content_key(content_key.key_inputs(run.spec, backend=run.backend, precision=run.precision))
        measurement = session.scalar(select(Measurement).where(Measurement.content_key == key))
        if measurement is None:
            continue
        detail = _apply_measurement(run, measurement)
        run.status, run.finished_at = CaseRunState.DONE, utcnow()
        session.add(Event(submission_id=submission.id, case_run_id=run.id, state=CaseRunState.DONE,
                          detail=f"{detail} (found when submitted)"))
    if not submission.case_runs or any(run.status not in TERMINAL for run in submission.case_runs):
        return False
    submission.grading_at = utcnow()
    touch(submission, SubmissionState.GRADING, "every case reuses a stored measurement", session=session)
    return True


def store_result(*, session: Session, run: CaseRun, result, key_inputs: dict[str, Any]) -> bool:
    """Record a CaseResult (ok or not) on the run; True when this moved the submission to grading.

    An ok result becomes a reusable Measurement under run.content_key, the key of `key_inputs` (grader.core.content_key).
    """
    provenance = result.provenance.model_dump(mode="json") if result.provenance else None
    run.result_status, run.error, run.wall_s = result.status, result.error, result.wall_s
    run.provenance, run.artifact_dir = provenance, result.out_dir
    run.metrics = result.metrics.model_dump(mode="json") if result.metrics is not None else None
    run.actual_backend = result.provenance.actual_backend if result.provenance else None
    run.stderr_tail = (result.stderr or "")[-4000:] or None
    store_evidence(session, run, result)
    if result.ok:
        _record_measurement(session, run, provenance, key_inputs)
    return _finish(session, run, status=CaseRunState.DONE if result.ok else CaseRunState.FAILED,
                   detail=f"{result.status} in {result.wall_s:.1f} s" + (f": {result.error}" if result.error else ""))


def _record_measurement(session: Session, run: CaseRun, provenance: dict, key_inputs: dict[str, Any]) -> None:
    try:
        with session.begin_nested():
            m = Measurement(content_key=run.content_key, key_inputs=key_inputs, case_run_id=run.id,
                            backend=run.actual_backend, provenance=provenance, metrics=run.metrics,
                            artifact_dir=run.artifact_dir)
            session.add(m)
        run.measurement_id = m.id
    except IntegrityError:
        pass  # the same key was measured concurrently (force_rerun); this run keeps its own evidence


def _finish(session: Session, run: CaseRun, *, status: str, error: str | None = None, detail: str | None = None) -> bool:
    lock_submission(session, run.submission_id)
    submission = session.get(Submission, run.submission_id)
    run.status, run.finished_at, run.lease_until = status, utcnow(), None
    if error:
        run.error = error
    session.add(Event(submission_id=run.submission_id, case_run_id=run.id, state=status, detail=detail or error))
    session.flush()
    open_runs = session.scalar(select(func.count()).select_from(CaseRun).where(  # audit re-runs never hold a grade
        CaseRun.submission_id == submission.id, CaseRun.purpose == CaseRunPurpose.GRADING, CaseRun.status.not_in(TERMINAL)))
    started = False
    if open_runs == 0:
        started = session.execute(
            update(Submission).where(Submission.id == submission.id, Submission.status == SubmissionState.RUNNING)
            .values(status=SubmissionState.GRADING, grading_at=utcnow(), updated_at=utcnow())
        ).rowcount == 1
        if started:
            session.add(Event(submission_id=submission.id, state=SubmissionState.GRADING))
    session.commit()
    return started


def touch(submission: Submission, state: str, detail: str | None = None, *, session: Session) -> None:
    """Move a submission to `state`, with a timestamped event."""
    submission.status = state
    submission.updated_at = utcnow()
    session.add(Event(submission_id=submission.id, state=state, detail=detail))


def store_evidence(session: Session, run: CaseRun, result) -> None:
    """The run's evidence row, from what the case process wrote (the folder it wrote to is read once, here, on the
    host that ran it). Replaces the row of an earlier try of a re-sent run, which no measurement used (only a failed
    or stuck run is re-sent). Committed by `_finish` with the run's state."""
    folder = Path(result.out_dir) / "arrays.npz" if result.out_dir else None
    if folder is not None and folder.is_file():
        arrays = folder.read_bytes()
    elif result.arrays:  # a result recorded without its folder: the same arrays, written as the engine writes them
        buffer = io.BytesIO()
        np.savez(buffer, **result.arrays)
        arrays = buffer.getvalue()
    else:
        arrays = None
    evidence = session.get(CaseEvidence, run.id) or CaseEvidence(case_run_id=run.id)
    evidence.arrays = arrays
    evidence.spec = result.spec.model_dump(mode="json", exclude_computed_fields=True)
    evidence.provenance = result.provenance.model_dump(mode="json") if result.provenance else None
    evidence.metrics = result.metrics.model_dump(mode="json") if result.metrics is not None else None
    limit = settings.evidence_output_max_bytes
    evidence.stdout, evidence.stderr = _bounded(result.stdout or "", limit), _bounded(result.stderr or "", limit)
    evidence.sizes = {name: len(body) for name in EVIDENCE_FILES
                      if (body := evidence_bytes(evidence, name)) is not None}
    evidence.stored_at = utcnow()
    session.add(evidence)


def _bounded(text: str, limit: int) -> str:
    """`text` whole when it fits `limit` bytes (UTF-8), else its last `limit` bytes after a line saying what was cut."""
    data = text.encode()
    if len(data) <= limit:
        return text
    return (f"[the first {len(data) - limit} of {len(data)} bytes were cut; the last {limit} are kept]\n"
            + data[-limit:].decode(errors="replace"))


def evidence_bytes(evidence: CaseEvidence, filename: str) -> bytes | None:
    """One evidence file's bytes as served (None when the run has none): the .npz as written, JSON indented."""
    if filename == "arrays.npz":
        return evidence.arrays
    if filename in ("stdout.txt", "stderr.txt"):
        text = getattr(evidence, filename.removesuffix(".txt"))
        return text.encode() if text is not None else None
    value = {"spec.json": evidence.spec, "provenance.json": evidence.provenance,
             "metrics.json": evidence.metrics}[filename]
    return json.dumps(value, indent=2).encode() if value is not None else None


def evidence_of(run: CaseRun) -> CaseEvidence | None:
    """The evidence a finished run stands on: its own, or that of the run whose measurement it reused. None while
    the run is not finished (a re-sent run's earlier try is not its evidence) or when none was stored."""
    if run.status not in TERMINAL:
        return None
    session = object_session(run)
    return session.get(CaseEvidence, run.reused_from_id or run.id) if session is not None else None


# Decoded arrays of recently read evidence, per process, by (evidence row, when it was stored): a class's 200 grades
# and lab checks read the same few dozen measurements again and again (each submission's 9 runs, twice), and reading
# one meant fetching its .npz from the database and parsing it. A row stored again (a re-sent run's new try) has a new
# stored_at, so a stale entry is never hit. Every reader gets arrays of its own (copies), as from np.load.
_ARRAYS: OrderedDict[tuple[int, datetime], dict[str, np.ndarray]] = OrderedDict()
_ARRAYS_LOCK = threading.Lock()  # an API process reads series on many threads
ARRAYS_CACHED = 256  # entries (a lesson case's .npz is 30-50 kB)


def _stored_arrays(run: CaseRun) -> dict[str, np.ndarray] | None:
    """The arrays of the evidence a finished run stands on (`evidence_of`'s row), or None when it has none."""
    session = object_session(run)
    if run.status not in TERMINAL or session is None:
        return None
    evidence_id = run.reused_from_id or run.id
    stored_at = session.scalar(select(CaseEvidence.stored_at).where(CaseEvidence.case_run_id == evidence_id))
    if stored_at is None:
        return None
    key = (evidence_id, stored_at)
    with _ARRAYS_LOCK:
        cached = _ARRAYS.get(key)
        if cached is not None:
            _ARRAYS.move_to_end(key)
    if cached is None:
        data = session.scalar(select(CaseEvidence.arrays).where(CaseEvidence.case_run_id == evidence_id))
        if data is None:
            return None
        with np.load(io.BytesIO(data), allow_pickle=False) as npz:
            cached = {name: npz[name] for name in npz.files}
        with _ARRAYS_LOCK:
            _ARRAYS[key] = cached
            while len(_ARRAYS) > ARRAYS_CACHED:
                _ARRAYS.popitem(last=False)
    return {name: array.copy() for name, array in cached.items()}


def stored_result(run: CaseRun):
    """The CaseResult a case run stands for, read back from the database: its provenance, metrics and the .npz
    bytes of its evidence (`evidence_of`); no file is read. Raises LookupError for an ok run without evidence."""
    spec = parse_case(run.spec)
    provenance = Provenance.model_validate(run.provenance) if run.provenance else None
    if run.status != CaseRunState.DONE or run.result_status != "ok":
        return CaseResult(spec=spec, status=run.result_status or "failed", provenance=provenance,
                          error=run.error or f"case run ended {run.status}", out_dir=run.artifact_dir)
    arrays = _stored_arrays(run)
    if arrays is None:
        raise LookupError(f"case run {run.id} ({run.name}) has no stored arrays")
    metrics = parse_metrics(run.metrics) if run.metrics else None
    return CaseResult(spec=spec, status="ok", arrays=arrays, provenance=provenance, metrics=metrics,
                      out_dir=run.artifact_dir, wall_s=run.wall_s or 0.0)
