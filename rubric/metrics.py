"""Trajectory metrics of the lesson's evidence table, computed from sampled arrays with numpy alone.

Each metric states what it measures and nothing more: a penetration *proxy* from sampled centre heights, contact
*presence* at samples, geometric separation only where no contact and positive clearance coincide, a stop only
where a full hold interval stays below the declared speed.
"""

from __future__ import annotations

import functools
import math
from typing import Annotated, Literal, Union

import numpy as np
from pydantic import BaseModel, Field, TypeAdapter

from .friction import effective_pair_friction
from .specs import ContactCase, FrictionCase


class ContactMetrics(BaseModel):
    kind: Literal["contact"] = "contact"
    case: str
    n_samples: int
    dt: float
    substeps: int
    substep_dt: float
    internal_updates: int
    duration_covered: float
    expected_center_z: float
    min_z: float
    penetration_proxy: float
    first_contact_index: int | None
    first_contact_time: float | None
    contact_samples: int
    min_clearance: float
    final_clearance: float
    separation_samples: int
    separation_duration: float
    max_upward_velocity_after_contact: float | None
    upward_samples_after_contact: int
    tail_window: float
    tail_settling_error: float
    tail_peak_to_peak: float
    max_tilt_deg: float
    passed_through: bool


class Alignment(BaseModel):
    """Two cases compared only at the sample times both recorded."""

    a: str
    b: str
    samples_a: int
    samples_b: int
    shared_samples: int
    first_shared_times: list[float]
    max_abs_diff: dict[str, float]


class Stop(BaseModel):
    stopped: bool
    index: int | None = None
    time: float | None = None
    distance: float | None = None
    detail: str


class LaneMetrics(BaseModel):
    case: str
    lane: str
    table_friction: float
    cube_friction: float
    # The value the engine assigned to this lane's cube-table contacts (None: no contact was ever reported) ...
    pair_friction: float | None
    # ... every distinct value it assigned (one, unless the engine treats contacts of one pair differently) ...
    pair_friction_values: list[float]
    # ... and the Python copy of the engine's rule (rubric.friction), a cross-check whose disagreement is visible.
    pair_friction_rule: float
    pair_friction_agrees: bool
    initial_vx: float
    stop: Stop
    final_displacement: float
    max_abs_omega: float
    stayed_on_table: bool
    # Largest angle (degrees) between the cube's own z axis and vertical over the measurement window, and whether it
    # passed the tip-over angle (tumble_angle_deg): the cube then fell onto another face, so part of its travel was
    # tumbling, not sliding. None for metrics stored before lane orientations were recorded (runner version < 3).
    max_tilt_deg: float | None = None
    tumbled: bool | None = None


def _ticks(t: np.ndarray) -> np.ndarray:
    """Sample times as integer nanoseconds, so shared times match exactly instead of by float equality."""
    return np.round(np.asarray(t, dtype=np.float64) * 1e9).astype(np.int64)


def contact_metrics(spec: ContactCase, arrays: dict[str, np.ndarray]) -> ContactMetrics:
    t, z, vz = arrays["t"], arrays["z"], arrays["vz"]
    count, clearance = arrays["contact_count"], arrays["clearance"]
    in_contact = count > 0
    contact_idx = np.flatnonzero(in_contact)
    first = int(contact_idx[0]) if contact_idx.size else None

    after = slice(first, None) if first is not None else slice(0, 0)
    separated = separation_mask(spec, arrays)[after]
    upward = vz[after] > spec.upward_speed_tolerance

    tail = t >= t[-1] - spec.tail_window + 1e-12
    z_tail = z[tail]
    return ContactMetrics(
        case=spec.name,
        n_samples=len(t),
        dt=spec.dt,
        substeps=spec.substeps,
        substep_dt=spec.substep_dt,
        internal_updates=spec.internal_updates,
        duration_covered=float(t[-1]) if len(t) else 0.0,
        expected_center_z=spec.expected_center_z,
        min_z=float(z.min()),
        penetration_proxy=penetration_proxy(z, spec.expected_center_z),
        first_contact_index=first,
        first_contact_time=float(t[first]) if first is not None else None,
        contact_samples=int(in_contact.sum()),
        min_clearance=float(clearance.min()),
        final_clearance=float(clearance[-1]),
        separation_samples=int(separated.sum()),
        # Quantized by the outer dt: an event shorter than one sample interval is invisible here.
        separation_duration=float(separated.sum() * spec.dt),
        max_upward_velocity_after_contact=float(vz[after].max()) if first is not None else None,
        upward_samples_after_contact=int(upward.sum()),
        tail_window=spec.tail_window,
        tail_settling_error=float(z_tail.mean() - spec.expected_center_z),
        tail_peak_to_peak=float(np.ptp(z_tail)),
        max_tilt_deg=float(np.degrees(tilt(arrays["quat"]).max())),
        # Centre below the table top: the cube is (at least half) through the table, not resting on it.
        passed_through=bool(z.min() < spec.table.top_z),
    )


def separation_mask(spec: ContactCase, arrays: dict[str, np.ndarray]) -> np.ndarray:
    """Samples of observed geometric separation: after first contact, no reported contact AND bottom clearance above
    the declared tolerance.

    Either signal alone is not separation: a zero contact count can occur while the cube still rests on the table,
    and before first contact the cube is falling, not separated. The check, the scoring and the figures all use this.
    """
    in_contact = arrays["contact_count"] > 0
    after_first_contact = np.cumsum(in_contact) > 0
    return after_first_contact & ~in_contact & (arrays["clearance"] > spec.separation_tolerance)


def penetration_proxy(z: np.ndarray, expected_center_z: float) -> float:
    """max(0, expected rest height - lowest sampled centre height); not the solver's continuous depth."""
    return max(0.0, float(expected_center_z - np.min(z)))


def tilt(quat_wxyz: np.ndarray) -> np.ndarray:
    """Angle (rad) between the cube's local z axis and world z; 0 while the aligned-cube assumption holds.

    Yaw leaves the bottom face flat, so only this tilt affects the penetration proxy's geometry.
    """
    w, x, y, _z = (quat_wxyz[:, i] for i in range(4))
    norm2 = np.sum(quat_wxyz**2, axis=1)
    r22 = 1.0 - 2.0 * (x * x + y * y) / norm2
    return np.arccos(np.clip(np.abs(r22), 0.0, 1.0))


def align(a_name: str, a: dict[str, np.ndarray], b_name: str, b: dict[str, np.ndarray], fields=("z", "vz")) -> Alignment:
    """Differences of `fields` at the sample times present in both records (N1 vs N4: 0.02, 0.04, ...)."""
    _, ia, ib = np.intersect1d(_ticks(a["t"]), _ticks(b["t"]), assume_unique=True, return_indices=True)
    diffs = {f: float(np.max(np.abs(a[f][ia] - b[f][ib]))) if ia.size else math.nan for f in fields}
    return Alignment(
        a=a_name,
        b=b_name,
        samples_a=len(a["t"]),
        samples_b=len(b["t"]),
        shared_samples=int(ia.size),
        first_shared_times=[round(float(v), 6) for v in a["t"][ia[:3]]],
        max_abs_diff=diffs,
    )


def sustained_stop(t: np.ndarray, x: np.ndarray, vx: np.ndarray, *, stop_speed: float, hold_steps: int) -> Stop:
    """First sample that starts a complete hold interval with |vx| < stop_speed throughout.

    The interval spans hold_steps outer steps (hold_steps + 1 samples) and must lie inside the record; no stop is
    ever inferred from the final sample.
    """
    below = np.abs(vx) < stop_speed
    window = hold_steps + 1
    if len(below) >= window:
        # run[i] = number of consecutive below-threshold samples starting at i
        run = np.zeros(len(below) + 1, dtype=np.int64)
        for i in range(len(below) - 1, -1, -1):
            run[i] = run[i + 1] + 1 if below[i] else 0
        starts = np.flatnonzero(run[:-1] >= window)
        if starts.size:
            i = int(starts[0])
            return Stop(
                stopped=True,
                index=i,
                time=float(t[i]),
                distance=float(x[i] - x[0]),
                detail=f"|vx| < {stop_speed} m/s from t={t[i]:.2f} s for {hold_steps} steps",
            )
    return Stop(stopped=False, detail=f"not stopped within the measured window (0 to {t[-1]:.2f} s)")


def tumble_angle_deg(width: float, height: float) -> float:
    """The tilt (degrees) past which a box resting on a face tips over onto the neighbouring face.

    A box tipping about one bottom edge is in balance when its centre of mass is straight above that edge: the tilt
    is then atan((width / 2) / (height / 2)). Below it, gravity's torque about the edge pulls the box back onto its
    face (it rocks); past it, the same torque carries it over onto the next face (it tumbles). For the lesson's cube
    (width = height) this is 45 degrees. It follows from the geometry alone, not from any measured run.
    """
    return math.degrees(math.atan2(width / 2, height / 2))


# One sentence for a student, shown wherever a tumbled lane is marked (figures, report page).
TUMBLE_EXPLANATION = ("A cube that tipped over onto another face travelled partly by tumbling, not sliding, so its "
                      "stop distance is not a sliding stop and cannot be compared with friction alone.")


def tumbled(max_tilt_deg: float, *, width: float, height: float) -> bool:
    """Whether a box that tipped up to max_tilt_deg went past its tip-over angle, i.e. fell onto another face."""
    return max_tilt_deg > tumble_angle_deg(width, height)


# float32 engine values vs the float64 rule: 0.3 is stored as 0.30000001.
PAIR_FRICTION_MATCH = 1e-6


def lane_metrics(spec: FrictionCase, arrays: dict[str, np.ndarray], lane: str) -> LaneMetrics:
    spec_lane = next(item for item in spec.lanes if item.name == lane)
    t, x, vx = arrays["t"], arrays[f"{lane}_x"], arrays[f"{lane}_vx"]
    tx, sx = spec.table.pos[0], spec.table.size[0]
    z = arrays[f"{lane}_z"]
    on_x = (x >= tx - sx / 2) & (x <= tx + sx / 2)
    in_contact = arrays[f"{lane}_contact_count"] > 0
    values = sorted({round(float(v), 7) for v in arrays[f"{lane}_contact_friction"][in_contact]})
    table_mu, cube_mu = float(arrays[f"{lane}_table_friction"]), float(arrays[f"{lane}_cube_friction"])
    rule = effective_pair_friction(table_mu, cube_mu)
    quat = arrays.get(f"{lane}_quat")  # absent only from arrays recorded before runner version 3
    # tilt() folds to 0..90 degrees; a cube that tips past 45 degrees reaches 90 on its way onto the next face, and the
    # 0.01 s samples cannot step over the 45..90 degree band (that would need over 78 rad/s about a horizontal axis).
    max_tilt = float(np.degrees(tilt(quat).max())) if quat is not None else None
    return LaneMetrics(
        case=spec.name,
        lane=lane,
        table_friction=table_mu,
        cube_friction=cube_mu,
        pair_friction=max(values) if values else None,
        pair_friction_values=values,
        pair_friction_rule=rule,
        pair_friction_agrees=bool(values) and all(abs(v - rule) <= PAIR_FRICTION_MATCH for v in values),
        initial_vx=float(vx[0]),
        stop=sustained_stop(t, x, vx, stop_speed=spec.stop_speed, hold_steps=spec.hold_steps),
        final_displacement=float(x[-1] - x[0]),
        max_abs_omega=float(np.max(np.linalg.norm(arrays[f"{lane}_omega"], axis=1))),
        # Centre over the table and not fallen below its top: the lane's geometry held for the whole run.
        stayed_on_table=bool(on_x.all() and (z > spec.table.top_z).all()),
        max_tilt_deg=max_tilt,
        tumbled=None if max_tilt is None else tumbled(max_tilt, width=spec.cube_size, height=spec.cube_size),
    )


class FrictionMetrics(BaseModel):
    kind: Literal["friction"] = "friction"
    case: str
    lanes: dict[str, LaneMetrics]

    def lane(self, name: str) -> LaneMetrics:
        return self.lanes[name]


CaseMetrics = Annotated[Union[ContactMetrics, FrictionMetrics], Field(discriminator="kind")]


def case_metrics(spec: ContactCase | FrictionCase, arrays: dict[str, np.ndarray]) -> ContactMetrics | FrictionMetrics:
    """Every metric of one validated case, computed once where the case ran and stored beside its arrays."""
    if isinstance(spec, ContactCase):
        return contact_metrics(spec, arrays)
    return FrictionMetrics(case=spec.name, lanes={lane.name: lane_metrics(spec, arrays, lane.name) for lane in spec.lanes})


@functools.cache
def _metrics_adapter() -> TypeAdapter:
    """Built once per process, as rubric.specs' case adapter (each TypeAdapter builds its validator anew)."""
    return TypeAdapter(CaseMetrics)


def parse_metrics(data: dict) -> ContactMetrics | FrictionMetrics:
    """Stored metrics (metrics.json or a database column) back into their model."""
    return _metrics_adapter().validate_python(data)
