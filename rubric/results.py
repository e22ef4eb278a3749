"""The measured-result contract between the runner and everything that reads evidence: arrays, provenance, status.

A result always exists, even for a case that crashed or timed out (status, error and captured output say why),
so nothing downstream ever has to guess whether a missing number means "not run" or "failed".
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from pydantic import BaseModel, ConfigDict

from .metrics import ContactMetrics, FrictionMetrics
from .specs import ContactCase, FrictionCase

# Bumped whenever the arrays or provenance a case writes change: measurements of another version are not reused.
RUNNER_VERSION = "3"

Status = Literal["ok", "failed", "invalid", "timeout"]


class Timings(BaseModel):
    model_config = ConfigDict(extra="forbid")

    import_s: float
    init_s: float
    build_s: float
    steps_s: float
    render_s: float = 0.0


class Discretization(BaseModel):
    """The lesson's timing quantities as the engine reports them for the measurement window (not the spec's)."""

    model_config = ConfigDict(extra="forbid")

    dt: float
    substeps: int
    substep_dt: float
    n_steps: int
    internal_updates: int
    duration: float
    sample_count: int
    settle_steps: int = 0


class Rendering(BaseModel):
    """Requested rendering mode and what came of it: OK with frames, or an explicit SKIP."""

    model_config = ConfigDict(extra="forbid")

    requested: bool
    status: Literal["OK", "SKIP"]
    frames: int
    detail: str


class Provenance(BaseModel):
    """Where a number came from. Written by the case process, checked by the parent before acceptance."""

    model_config = ConfigDict(extra="forbid")

    case: str
    requested_backend: str
    actual_backend: str
    torch_device: str
    device_name: str
    torch_hip: str | None
    torch_cuda: str | None
    versions: dict[str, str]
    precision: str
    seed: int
    deterministic_algorithms: bool
    execution_mode: Literal["isolated", "warm"]
    # Which scene produced the arrays: built for this case, or built for an earlier case of the same structure and
    # reset (worker.engine.structure_key). Absent in results stored before scene reuse existed: those were fresh.
    scene: Literal["fresh", "reused"] = "fresh"
    host: str
    pid: int
    timings: Timings
    discretization: Discretization
    rendering: Rendering
    runner_version: str
    exit_status: int


@dataclass
class CaseResult:
    """One case's outcome. `arrays` is empty unless the case process wrote them; failures keep their evidence."""

    spec: ContactCase | FrictionCase
    status: Status
    arrays: dict[str, np.ndarray] = field(default_factory=dict)
    provenance: Provenance | None = None
    # Computed once from the validated arrays where the case ran (metrics.json beside them); None unless ok.
    metrics: ContactMetrics | FrictionMetrics | None = None
    error: str | None = None
    stdout: str = ""
    stderr: str = ""
    out_dir: str | None = None
    wall_s: float = 0.0

    @property
    def ok(self) -> bool:
        return self.status == "ok"

    @property
    def backend(self) -> str:
        """The backend that produced the numbers; the requested one when nothing was produced."""
        return self.provenance.actual_backend if self.provenance else self.spec.backend


FRAME_FIELDS = ("frame_initial", "frame_final")


def expected_arrays(spec: ContactCase | FrictionCase) -> dict[str, tuple[tuple[int, ...] | None, str]]:
    """Array name -> (shape, dtype kind) that a valid result of `spec` must contain. None shape: a frame."""
    n = spec.sample_count
    if isinstance(spec, ContactCase):
        fields = {
            "t": ((n,), "f"),
            "z": ((n,), "f"),
            "vz": ((n,), "f"),
            "contact_count": ((n,), "i"),
            "clearance": ((n,), "f"),
            "quat": ((n, 4), "f"),
        }
    else:
        fields = {"t": ((n,), "f")}
        for lane in spec.lanes:
            p = lane.name
            fields |= {
                f"{p}_x": ((n,), "f"),
                f"{p}_y": ((n,), "f"),
                f"{p}_z": ((n,), "f"),
                f"{p}_vx": ((n,), "f"),
                f"{p}_omega": ((n, 3), "f"),
                # Orientation quaternion (w, x, y, z): whether the cube tipped over onto another face.
                f"{p}_quat": ((n, 4), "f"),
                f"{p}_contact_count": ((n,), "i"),
                # Sliding friction the engine assigned to the lane's cube-table contacts at each sample (0: none).
                f"{p}_contact_friction": ((n,), "f"),
                f"{p}_table_friction": ((), "f"),
                f"{p}_cube_friction": ((), "f"),
            }
    for name in FRAME_FIELDS:
        fields[name] = (None, "u")
    return fields


def validate_arrays(spec: ContactCase | FrictionCase, arrays: dict[str, np.ndarray], *, render: bool) -> list[str]:
    """Every reason these arrays cannot be accepted as a result of `spec`; empty when they can."""
    from .lesson import expected_arrays as declared  # any installed lesson's kind, by its declaration

    problems = []
    expected = declared(spec)
    for name in sorted(set(expected) - set(arrays)):
        problems.append(f"{name}: missing")
    for name in sorted(set(arrays) - set(expected)):
        problems.append(f"{name}: unexpected field")
    for name, (shape, kind) in expected.items():
        if name not in arrays:
            continue
        a = arrays[name]
        if a.dtype.kind != kind:
            problems.append(f"{name}: dtype {a.dtype} is not of kind '{kind}'")
            continue
        if shape is None:
            problems += _frame_problems(name, a, render=render)
        elif a.shape != shape:
            problems.append(f"{name}: shape {a.shape}, expected {shape}")
        elif kind == "f" and not np.all(np.isfinite(a)):
            bad = np.argwhere(~np.isfinite(a))[0]
            sample = int(bad[0]) if bad.size else 0
            t = arrays.get("t")
            when = f" (t={float(t[sample]):.4f} s)" if t is not None and a.ndim and sample < len(t) else ""
            problems.append(f"{name}: first non-finite value at sample {sample}{when}")
    return problems


def _frame_problems(name: str, frame: np.ndarray, *, render: bool) -> list[str]:
    if not render:
        return [] if frame.size == 0 else [f"{name}: rendering disabled but a non-empty frame was returned"]
    if frame.ndim != 3 or frame.shape[2] != 3 or frame.shape[0] == 0 or frame.shape[1] == 0:
        return [f"{name}: expected a non-empty HxWx3 RGB frame, got shape {frame.shape}"]
    if frame.max() == frame.min():
        return [f"{name}: frame is a single flat value ({int(frame.max())}); the camera saw nothing"]
    return []


def spec_discretization(spec: ContactCase | FrictionCase) -> Discretization:
    """What the engine should report for `spec`: the lesson's derived quantities computed from its inputs."""
    return Discretization(
        dt=spec.dt, substeps=spec.substeps, substep_dt=spec.substep_dt, n_steps=spec.n_steps,
        internal_updates=spec.internal_updates, duration=spec.duration, sample_count=spec.sample_count,
        settle_steps=getattr(spec, "settle_steps", 0),
    )


def discretization_problems(spec: ContactCase | FrictionCase, reported: Discretization,
                            t: np.ndarray | None = None) -> list[str]:
    """Where the engine's reported discretization, or the sampled time axis, disagrees with the spec.

    Counts must match exactly; times to float precision (the engine accumulates substeps x substep_dt).
    """
    problems = []
    want = spec_discretization(spec)
    for name, value in want.model_dump().items():
        got = getattr(reported, name)
        same = got == value if isinstance(value, int) else math.isclose(got, value, rel_tol=1e-6, abs_tol=1e-12)
        if not same:
            problems.append(f"provenance.discretization.{name}: engine reported {got!r}, the spec derives {value!r}")
    if t is not None and t.ndim == 1 and len(t) >= 2 and np.all(np.isfinite(t)):
        steps = np.diff(t)
        if not np.allclose(steps, reported.dt, rtol=1e-6, atol=1e-9):
            problems.append(f"t: sample spacing {steps.min():.6g}..{steps.max():.6g} s, engine dt {reported.dt:g} s")
        # samples taken after every outer step cover one step more than their first-to-last span; a first sample
        # at measurement time zero (one more sample than steps) does not
        span = float(t[-1] - t[0]) + (reported.dt if spec.sample_count == spec.n_steps else 0.0)
        if not math.isclose(span, reported.duration, rel_tol=1e-6, abs_tol=1e-9):
            problems.append(f"t: samples cover {span:.6g} s, engine duration {reported.duration:.6g} s")
    return problems
