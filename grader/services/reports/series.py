"""The report's charts as data: the series its browser charts draw (grader/static/report_charts.js), read from the
arrays stored in the database, and the list of charts with a text caption of their key numbers.

Why data and not pictures: drawing a submission's 18 PNGs cost more server CPU than its simulation and the PNGs lived
on the drawing worker's disk (issue 24; `python -m tools.bench --only figures` measures both ways, docs/benchmark.md).
The series are what the PNGs showed, nothing more: each case run's measured trajectories and its stored
metrics (first contact, stops, pair frictions), never an item's score, verdict, expected value or tolerance, and never
the lab check. So they follow the rule the PNGs and the evidence downloads followed: whoever may read the
submission (grader.services.identity.access) may read them, except the runs whose measurements decide an item withheld from
the reader (`GradeView.withheld_runs`, grader.services.submissions.visibility): those are named, with why, and carry no series,
metric or caption until the item is shown.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from grader.core.lifecycle import stored_result
from grader.core.models import CaseRun, Submission
from rubric import CaseResult, ContactCase, FrictionCase
from rubric.lesson import LessonNotFound, lesson

# Significant digits kept per value: float32 measurements carry about 7, and a chart (or a reader) needs fewer.
DIGITS = 6
# Changes when the series' JSON changes shape, so a browser's copy from an older release is never confirmed (ETag).
SHAPE = "2"
CONTACT_CHARTS = ("contact-z", "contact-vz", "contact-count", "contact-clearance")
FRICTION_CHARTS = ("friction-x", "friction-vx", "friction-omega")


def compact(values) -> list:
    """An array as a JSON list rounded to DIGITS significant digits (about 3x smaller than float64 reprs); NaN and
    infinities become null, which JSON can carry and a chart leaves as a gap."""
    a = np.asarray(values, dtype=float)
    finite = np.isfinite(a)
    peak = float(np.abs(a[finite]).max()) if finite.any() else 0.0
    decimals = DIGITS - 1 - (math.floor(math.log10(peak)) if peak > 0 else 0)
    rounded = np.round(a, max(decimals, 0)).tolist()
    return [v if f else None for v, f in zip(rounded, finite.tolist())] if not finite.all() else rounded


def _hex(color) -> str:
    return "#" + "".join(f"{round(255 * max(0.0, min(1.0, c))):02x}" for c in color)


def _contact(result: CaseResult) -> dict:
    spec: ContactCase = result.spec
    a, m = result.arrays, result.metrics
    return {
        "dt": spec.dt, "substeps": spec.substeps, "substep_dt": spec.substep_dt,
        "expected_center_z": spec.expected_center_z, "separation_tolerance": spec.separation_tolerance,
        "metrics": {"first_contact_time": m.first_contact_time, "penetration_proxy": m.penetration_proxy,
                    "min_clearance": m.min_clearance, "final_clearance": m.final_clearance,
                    "separation_samples": m.separation_samples, "separation_duration": m.separation_duration},
        "series": {"t": compact(a["t"]), "z": compact(a["z"]), "vz": compact(a["vz"]),
                   "contact_count": np.asarray(a["contact_count"]).astype(int).tolist(),
                   "clearance_mm": compact(np.asarray(a["clearance"]) * 1e3)},
    }


def _lane(result: CaseResult, lane) -> dict:
    a, m = result.arrays, result.metrics.lane(lane.name)
    x = np.asarray(a[f"{lane.name}_x"], dtype=float)
    return {
        "name": lane.name, "color": _hex(lane.color), "cube_friction": m.cube_friction,
        "table_friction": m.table_friction, "pair_friction": m.pair_friction, "tumbled": m.tumbled,
        "max_tilt_deg": m.max_tilt_deg, "final_displacement": m.final_displacement,
        "stop": m.stop.model_dump(mode="json"),
        "x": compact(x - x[0]), "vx": compact(a[f"{lane.name}_vx"]),
        "omega": compact(np.linalg.norm(np.asarray(a[f"{lane.name}_omega"], dtype=float), axis=1)),
    }


def _friction(result: CaseResult) -> dict:
    spec: FrictionCase = result.spec
    return {"dt": spec.dt, "substeps": spec.substeps, "table_friction": spec.table.friction,
            "stop_speed": spec.stop_speed, "hold": spec.hold,
            "series": {"t": compact(result.arrays["t"])},
            "lanes": [_lane(result, lane) for lane in spec.lanes]}


def _run(submission: Submission, run: CaseRun, withheld: Mapping[str, str]) -> dict:
    entry = {"name": run.name, "kind": run.kind, "status": run.result_status or run.status,
             "backend": run.actual_backend or run.backend}
    if run.name in withheld:  # its measurements decide an item withheld from this reader: named, never drawn
        return entry | {"status": "withheld", "withheld": withheld[run.name]}
    entry["data"] = f"/submissions/{submission.id}/case-runs/{run.name}/arrays.npz"
    try:
        result = stored_result(run)
    except LookupError as exc:  # an ok run without stored arrays: said, never drawn as if empty
        return entry | {"status": "unreadable", "error": str(exc)}
    if not (result.ok and result.arrays and result.metrics is not None):
        return entry | {"error": result.error or f"case run {run.status}"}
    genesis = result.provenance.versions.get("genesis") if result.provenance else None
    entry |= {"genesis": genesis, "execution": result.provenance.execution_mode if result.provenance else None}
    if isinstance(result.spec, ContactCase):
        return entry | _contact(result)
    if isinstance(result.spec, FrictionCase):
        return entry | _friction(result)
    return entry | _sampled(result)


def _sampled(result: CaseResult) -> dict:
    """A run of a kind the report draws no chart of (another lesson's): its timing, its metrics and every sampled
    series (the one-dimensional arrays, one value per sample), so that the data behind its grade is there to read."""
    n = len(result.arrays.get("t", ()))
    return {"dt": result.spec.dt, "substeps": result.spec.substeps, "substep_dt": result.spec.substep_dt,
            "metrics": result.metrics.model_dump(mode="json", exclude={"kind", "case"}),
            "series": {name: compact(values) for name, values in result.arrays.items()
                       if np.ndim(values) == 1 and len(values) == n and np.asarray(values).dtype.kind in "fiu"}}


def submission_series(*, submission: Submission, withheld: Mapping[str, str] | None = None) -> dict:
    """Every case run of the submission with what its charts draw (runs without a result say why): one JSON
    document, read from the database only. `withheld`: {run name: why} of the runs the reader may not see yet
    (GradeView.withheld_runs), listed without their series or metrics."""
    withheld = withheld or {}
    return {"submission": submission.id, "digits": DIGITS, "withheld": dict(withheld),
            "runs": [_run(submission, run, withheld) for run in submission.case_runs]}


@dataclass(frozen=True)
class Chart:
    """One chart of the report: which drawing (`kind`), of which run (friction charts), and its text alternative.
    A chart the lesson declares (rubric.lesson.SeriesChart) has kind "series-ID" and says what it draws: the sampled
    `series` of every run of `run_kind`, its `title` (English; the page translates it), its y `axis`, and the metric
    holding a run's first contact time (`first_contact`), if any."""

    kind: str
    run: str
    caption: str
    title: str = ""
    series: str = ""
    run_kind: str = ""
    axis: str = ""
    first_contact: str = ""
    stepped: bool = False

    @property
    def id(self) -> str:
        return f"{self.kind}-{self.run}" if self.run else self.kind


def _ok(run: CaseRun) -> bool:
    return run.result_status == "ok" and bool(run.metrics)


def _first(m: dict) -> str:
    t = m.get("first_contact_time")
    return f"first contact t={t:.3f} s" if t is not None else "no contact reported"


# Per contact chart, what its caption says of each case: the numbers a reader looks for in that chart.
CONTACT_WORDS = {
    "contact-z": lambda m: (f"lowest z {m['min_z']:.4f} m against the ideal rest height {m['expected_center_z']:.4f} m "
                            f"(penetration proxy {m['penetration_proxy'] * 1e3:.2f} mm), {_first(m)}"),
    "contact-vz": lambda m: (f"{_first(m)}; after it, " + (
        f"largest upward velocity {m['max_upward_velocity_after_contact']:.3f} m/s over "
        f"{m['upward_samples_after_contact']} upward samples" if m.get("max_upward_velocity_after_contact") is not None
        else "no upward velocity")),
    "contact-count": lambda m: f"{_first(m)}, {m['contact_samples']} of {m['n_samples']} samples in contact",
    "contact-clearance": lambda m: (f"min clearance {m['min_clearance'] * 1e3:+.2f} mm, final "
                                    f"{m['final_clearance'] * 1e3:+.2f} mm, {m['separation_samples']} separation "
                                    f"samples ({m['separation_duration']:.2f} s)"),
}


def _contact_caption(kind: str, runs: list[CaseRun]) -> str:
    return "; ".join(f"{run.name} (dt={run.metrics['dt']:g} s, substeps={run.metrics['substeps']}): "
                     f"{CONTACT_WORDS[kind](run.metrics)}" for run in runs)


def _lane_words(kind: str, lane: dict) -> str:
    stop = lane["stop"]
    if kind == "friction-x":
        words = (f"stopped after {stop['distance']:.3f} m at t={stop['time']:.2f} s" if stop["stopped"]
                 else f"not stopped, final displacement {lane['final_displacement']:.3f} m")
    elif kind == "friction-vx":
        words = f"initial vx {lane['initial_vx']:.3f} m/s, " + (
            f"below the stop band from t={stop['time']:.2f} s" if stop["stopped"] else "never held in the stop band")
    else:
        words = f"largest |\u03c9| {lane['max_abs_omega']:.3f} rad/s" + (
            f", max tilt {lane['max_tilt_deg']:.1f}\u00b0" if lane.get("max_tilt_deg") is not None else "")
    pair = f"{lane['pair_friction']:.2f}" if lane["pair_friction"] is not None else "no contact"
    tumbled = (f", TUMBLED (max tilt {lane['max_tilt_deg']:.1f}\u00b0): not a sliding stop" if lane.get("tumbled")
               else "")
    return f"{lane['lane']} (cube \u03bc={lane['cube_friction']:.2f}, pair \u03bc={pair}): {words}{tumbled}"


def _lane_caption(kind: str, run: CaseRun) -> str:
    return f"table \u03bc={_table(run):.2f}; " + "; ".join(_lane_words(kind, lane) for lane in run.metrics["lanes"].values())


def _table(run: CaseRun) -> float:
    return next(iter(run.metrics["lanes"].values()))["table_friction"]


def report_charts(submission: Submission, withheld: Mapping[str, str] | None = None) -> list[Chart]:
    """The charts a report shows, with captions from the runs' stored metrics (no arrays read: the page stays
    cheap; the browser fetches the series). Contact charts overlay every contact run; friction charts are per run.
    The runs in `withheld` (GradeView.withheld_runs) are in no chart and no caption."""
    ok = [r for r in submission.case_runs if _ok(r) and r.name not in (withheld or {})]
    contact = [r for r in ok if r.metrics.get("kind") == "contact"]
    charts = [Chart(kind, "", _contact_caption(kind, contact)) for kind in CONTACT_CHARTS] if contact else []
    for run in (r for r in ok if r.metrics.get("kind") == "friction"):
        charts += [Chart(kind, run.name, _lane_caption(kind, run)) for kind in FRICTION_CHARTS]
    return charts + _lesson_charts(submission.lesson, ok)


def _lesson_charts(name: str, ok: list[CaseRun]) -> list[Chart]:
    """The charts the submission's lesson declares (rubric.lesson.SeriesChart), each over its runs of the chart's
    case kind; a chart with no such run is left out."""
    try:
        declared = lesson(name).charts
    except LessonNotFound:  # a lesson no longer installed: its runs keep their data, listed without charts
        return []
    charts = []
    for chart in declared:
        runs = [r for r in ok if r.metrics.get("kind") == chart.kind]
        if runs:
            caption = "; ".join(f"{run.name} (dt={run.spec['dt']:g} s, substeps={run.spec['substeps']}): "
                                f"{chart.words(run.metrics)}" for run in runs)
            charts.append(Chart(f"series-{chart.id}", "", caption, title=chart.title, series=chart.series,
                                run_kind=chart.kind, axis=chart.axis, first_contact=chart.first_contact,
                                stepped=chart.stepped))
    return charts
