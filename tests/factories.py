"""Test helpers defined once: example sheet, users and tokens, lane configs, import checks, hand-made case folders."""

from __future__ import annotations

import copy
import json
import subprocess
import sys
from collections.abc import Iterable
from pathlib import Path

import numpy as np
import yaml

ROOT = Path(__file__).resolve().parent.parent
EXAMPLES = ROOT / "examples" / "l03"
REFERENCE_YAML = EXAMPLES / "reference.yaml"
_REFERENCE = yaml.safe_load(REFERENCE_YAML.read_text())

# Who uses the service in tests: (name, role, course index into the two courses given to `create_people`).
PEOPLE = (("alice", "student", 0), ("bob", "student", 0), ("prof", "instructor", 0), ("tess", "auditor", 0),
          ("eve", "instructor", 1))


def reference_sheet() -> dict:
    """A fresh copy of the lesson's example sheet (examples/l03/reference.yaml); callers may edit it."""
    return copy.deepcopy(_REFERENCE)


def create_people(session, *, course: str, other_course: str) -> dict[str, str]:
    """The course's students, instructor and auditor, plus an instructor of another course; their API tokens by name."""
    from grader.services.identity import accounts

    courses = [accounts.get_or_create_course(session=session, name=name) for name in (course, other_course)]
    tokens = {}
    for name, role, index in PEOPLE:
        user = accounts.get_or_create_user(session=session, course=courses[index], name=name, role=role)
        tokens[name] = accounts.create_token(session=session, user=user)
    return tokens


def two_lanes(low_friction: float = 0.10, high_friction: float = 0.80, *, swap_colors: bool = False) -> list[dict]:
    """The friction case's two lanes as sheet config, optionally with other frictions or the Surface colours swapped."""
    orange, blue = [1.0, 0.5, 0.0], [0.1, 0.3, 1.0]
    low_color, high_color = (blue, orange) if swap_colors else (orange, blue)
    return [{"name": "low", "friction": low_friction, "y": -0.15, "color": low_color},
            {"name": "high", "friction": high_friction, "y": 0.15, "color": high_color}]


def sheet_results(measured: dict) -> dict:
    """Results for the reference sheet: its configs equal friction-table-0.30 and N5 up to their names."""
    from rubric.scoring import SHEET_CASE_PREFIX

    return {**measured, SHEET_CASE_PREFIX + "table_exercise": measured["friction-table-0.30"],
            SHEET_CASE_PREFIX + "extension": measured["N5"]}


def heavy_imports(modules: Iterable[str], watch: Iterable[str] = ("genesis", "torch")) -> list[str]:
    """Which of `watch` a fresh interpreter has loaded after importing `modules` (an import error fails loudly)."""
    code = (f"import json, sys; import {', '.join(modules)}; "
            f"print(json.dumps(sorted(m for m in {sorted(watch)!r} if m in sys.modules)))")
    done = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout.strip().splitlines()[-1])


def provenance(spec, **over) -> dict:
    """What a case process that ran `spec` as asked on CPU would write to provenance.json; `over` replaces fields."""
    from rubric.results import spec_discretization

    p = {
        "case": spec.name, "requested_backend": spec.backend, "actual_backend": spec.backend,
        "torch_device": "cpu", "device_name": "test cpu", "torch_hip": None, "torch_cuda": None,
        "versions": {"genesis": "1.3.3"}, "precision": spec.precision, "seed": spec.seed,
        "deterministic_algorithms": False, "execution_mode": "isolated", "host": "h", "pid": 1,
        "timings": {"import_s": 1, "init_s": 1, "build_s": 1, "steps_s": 1},
        "rendering": {"requested": False, "status": "SKIP", "frames": 0, "detail": "off"},
        "runner_version": "2", "exit_status": 0,
        # What the engine reports when it ran the spec as specified.
        "discretization": spec_discretization(spec).model_dump(),
    }
    return p | over


def contact_arrays(n: int = 75, dt: float = 0.02) -> dict[str, np.ndarray]:
    """A contact case's arrays: a cube resting at z=0.77 for n samples (N3 has 75 at dt 0.02)."""
    return {
        "t": np.arange(1, n + 1) * dt, "z": np.full(n, 0.77), "vz": np.zeros(n),
        "contact_count": np.zeros(n, dtype=np.int32), "clearance": np.zeros(n), "quat": np.tile([1.0, 0, 0, 0], (n, 1)),
        "frame_initial": np.zeros((0, 0, 3), np.uint8), "frame_final": np.zeros((0, 0, 3), np.uint8),
    }


def write_case_folder(out: Path, arrays: dict, provenance: dict) -> None:
    """What a case process leaves behind on success: arrays.npz and provenance.json."""
    np.savez(out / "arrays.npz", **arrays)
    (out / "provenance.json").write_text(json.dumps(provenance))


def rubric_v3(**tolerance_values: float) -> dict:
    """L03 v2's content published as v3 with its own review record and the given tolerances re-reviewed at new
    values (a regrade test's new version; nothing here is shipped in rubric/lessons)."""
    import datetime as dt

    from rubric.rubrics import load_rubric

    content = load_rubric("L03", "2").model_dump(mode="json")
    today = dt.date(2026, 11, 24).isoformat()  # not a clock time: a review record's date, compared with nothing
    content["version"] = "3"
    content["review"] = {"reviewer": "regrade test instructor", "review_date": today,
                         "notes": "tightened for the regrade tests"}
    for name, value in tolerance_values.items():
        content["tolerances"][name] |= {
            "value": value, "reviewer": "regrade test instructor", "review_date": today,
            "rationale": f"regrade test: {name} reviewed to {value:g} {content['tolerances'][name]['unit']} to see "
                         "which verdicts a tighter range changes"}
    return content


def mark_measured(run, result, *, artifact_dir=None) -> None:
    """Record a real CaseResult on a case run as the worker leaves a measured run: done, ok, its provenance, metrics
    and arrays' folder (`artifact_dir`, default where the result was written), and its evidence in the database."""
    from sqlalchemy.orm import object_session

    from grader.core.lifecycle import store_evidence
    from grader.core.models import utcnow

    run.status, run.result_status, run.artifact_dir = "done", "ok", str(artifact_dir or result.out_dir)
    run.provenance = result.provenance.model_dump(mode="json")
    run.metrics = result.metrics.model_dump(mode="json")
    run.actual_backend, run.wall_s, run.finished_at = result.provenance.actual_backend, result.wall_s, utcnow()
    store_evidence(object_session(run), run, result)  # the evidence row the worker stores with the run


def store_lesson_runs(session, measured: dict, *, by: str) -> dict[str, int]:
    """Store the lesson's own cases (rubric.scoring.LESSON_RUNS) as measured (`measured`: real CaseResults by name),
    as the done case runs of one submission by user `by` and their reusable Measurements, as a worker that ran them
    would have left them; commits. Their case run ids by name."""
    from sqlalchemy import select

    from grader.services.submissions import submit as submissions
    from grader.core.models import User
    from rubric import BASELINE_CASES
    from rubric.scoring import LESSON_RUNS

    from grader.core.models import Measurement
    from grader.core import content_key as reuse

    user = session.scalar(select(User).where(User.name == by))
    earlier = submissions.create_submission(session=session, student=user, lesson="L03", sheet=reference_sheet(),
                                     specs=[BASELINE_CASES[name] for name in LESSON_RUNS], force_rerun=False)
    session.flush()
    for run in earlier.case_runs:
        mark_measured(run, measured[run.name])
        inputs = reuse.key_inputs(run.spec, backend=run.backend, precision=run.precision)
        run.content_key = reuse.content_key(inputs)
        session.add(Measurement(content_key=run.content_key, key_inputs=inputs, case_run_id=run.id,
                                backend=run.actual_backend, provenance=run.provenance, metrics=run.metrics,
                                artifact_dir=run.artifact_dir))
    session.commit()
    return {run.name: run.id for run in earlier.case_runs}


def audit_entry_for(run, **fields):
    """An AuditEntry comparing a case run with itself (cpu 32 against cpu 64, warm), as the audit would store it."""
    from grader.core.models import AuditEntry

    values = dict(course_id=run.submission.course_id, lesson="L03", case=run.name, spec_key=run.spec_key,
                  spec=run.spec, left_case_run_id=run.id, right_case_run_id=run.id, left_variant="cpu/32/warm",
                  right_variant="cpu/64/warm", classification="numeric_drift", summary="stored by the test",
                  figures=[])
    return AuditEntry(**(values | fields))
