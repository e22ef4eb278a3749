"""Recorded-style results for rubric tests that need no Genesis: each case "run" by a few lines of textbook physics
shaped like the engine's records, then validated and measured by the real rubric code (validate_arrays, case_metrics).

Not a model of Genesis: a fixture with the relations the lesson teaches built in, so tests of grading under a variant
can vary parameters freely. The contact cube falls freely, overshoots its resting height by 1.3 x substep_dt (finer
internal steps penetrate less; N1 and N4 agree) and settles; each lane slides at the max-rule pair friction.
"""

from __future__ import annotations

import numpy as np

from rubric.friction import effective_pair_friction
from rubric.metrics import case_metrics
from rubric.results import CaseResult, Provenance, validate_arrays
from rubric.specs import ContactCase, FrictionCase
from tests.factories import provenance

EMPTY_FRAME = np.zeros((0, 0, 3), np.uint8)


def _contact(spec: ContactCase) -> dict[str, np.ndarray]:
    n, g = spec.sample_count, -spec.gravity[2]
    t = np.arange(1, n + 1) * spec.dt
    rest, z0 = spec.expected_center_z, spec.cube.pos[2]
    t_impact = np.sqrt(2 * (z0 - rest) / g)
    depth = 1.3 * spec.substep_dt
    z = np.where(t < t_impact, z0 - g * t**2 / 2,
                 np.where(t < t_impact + 0.2, rest - depth, rest - depth * np.exp(-(t - t_impact - 0.2) / 0.03)))
    vz = np.where(t < t_impact, -g * t, 0.0)
    return {"t": t, "z": z, "vz": vz, "contact_count": np.where(t >= t_impact, 4, 0).astype(np.int32),
            "clearance": z - spec.cube.size / 2 - spec.table.top_z, "quat": np.tile([1.0, 0, 0, 0], (n, 1)),
            "frame_initial": EMPTY_FRAME, "frame_final": EMPTY_FRAME}


def _friction(spec: FrictionCase) -> dict[str, np.ndarray]:
    n, g = spec.sample_count, -spec.gravity[2]
    t = np.arange(n) * spec.dt
    arrays = {"t": t, "frame_initial": EMPTY_FRAME, "frame_final": EMPTY_FRAME}
    for lane in spec.lanes:
        mu = effective_pair_friction(spec.table.friction, lane.friction)
        v0 = spec.initial_speed
        t_stop = v0 / (mu * g)
        moving = t < t_stop
        vx = np.where(moving, v0 - mu * g * t, 0.0)
        x = spec.start_x + np.where(moving, v0 * t - mu * g * t**2 / 2, v0**2 / (2 * mu * g))
        p = lane.name
        arrays |= {
            f"{p}_x": x, f"{p}_y": np.full(n, lane.y), f"{p}_z": np.full(n, spec.rest_z), f"{p}_vx": vx,
            f"{p}_omega": np.zeros((n, 3)), f"{p}_quat": np.tile([1.0, 0, 0, 0], (n, 1)),
            f"{p}_contact_count": np.full(n, 4, np.int32), f"{p}_contact_friction": np.full(n, mu),
            f"{p}_table_friction": np.array(spec.table.friction), f"{p}_cube_friction": np.array(lane.friction),
        }
    return arrays


def synthetic_result(spec: ContactCase | FrictionCase) -> CaseResult:
    arrays = _contact(spec) if isinstance(spec, ContactCase) else _friction(spec)
    problems = validate_arrays(spec, arrays, render=False)
    assert not problems, problems  # the fixture writes what a valid case writes
    return CaseResult(spec=spec, status="ok", arrays=arrays, provenance=Provenance(**provenance(spec)),
                      metrics=case_metrics(spec, arrays))


def synthetic_runs(specs) -> dict[str, CaseResult]:
    """Results keyed by case name, as the worker returns them for cases_to_run(...)."""
    return {spec.name: synthetic_result(spec) for spec in specs}
