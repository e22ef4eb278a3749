"""The lesson's relations between measured cases, each judged one way under a reviewed tolerance.

The lab check and the scoring both read these, so "did substeps reduce the proxy", "do N1 and N4 agree", "which
lane is the low-friction one", "how did a lane's stop change" and "did swapping colours change anything" each have
exactly one definition.
"""

from __future__ import annotations

import numpy as np
from pydantic import BaseModel

from .metrics import Alignment, ContactMetrics, FrictionMetrics, LaneMetrics
from .results import FRAME_FIELDS


def direction(delta: float, tol: float, *, down: str, up: str) -> str | None:
    """The measured direction of a difference; None when it lies inside the resolution tolerance."""
    if abs(delta) <= tol:
        return None
    return up if delta > 0 else down


class ProxyChange(BaseModel):
    coarse: str
    fine: str
    coarse_proxy: float
    fine_proxy: float
    valid: bool  # both cases made contact and neither passed through: otherwise the proxy means nothing
    direction: str | None  # "decrease" | "increase" | None (inside tolerance)

    def describe(self) -> str:
        if not self.valid:
            return f"{self.coarse} vs {self.fine}: no valid contact in both cases, so the proxy comparison is meaningless"
        return (f"{self.coarse} {self.coarse_proxy * 1000:.3f} mm -> {self.fine} {self.fine_proxy * 1000:.3f} mm "
                f"({self.direction or 'inside tolerance'})")


def proxy_change(coarse: ContactMetrics, fine: ContactMetrics, tol: float) -> ProxyChange:
    """How the penetration proxy moved from the coarser to the finer internal timestep."""
    valid = all(m.first_contact_index is not None and not m.passed_through for m in (coarse, fine))
    delta = fine.penetration_proxy - coarse.penetration_proxy
    return ProxyChange(coarse=coarse.case, fine=fine.case, coarse_proxy=coarse.penetration_proxy,
                       fine_proxy=fine.penetration_proxy, valid=valid,
                       direction=direction(delta, tol, down="decrease", up="increase") if valid else None)


def cases_agree(alignment: Alignment, *, dz_tol: float, dvz_tol: float) -> bool:
    """Two contact cases agree when they share sample times and z and vz stay within tolerance at every one."""
    return (alignment.shared_samples > 0 and alignment.max_abs_diff["z"] <= dz_tol
            and alignment.max_abs_diff["vz"] <= dvz_tol)


def lanes_by_pair(friction: FrictionMetrics) -> tuple[LaneMetrics, LaneMetrics]:
    """(low, high): the lanes with the lowest and highest effective pair friction the engine used.

    The lesson's "low-friction lane" is the one whose *pair* value is lower, whatever the lanes are named.
    """
    lanes = sorted(friction.lanes.values(), key=lambda m: (m.pair_friction is None, m.pair_friction or 0.0))
    return lanes[0], lanes[-1]


def stop_change(before: LaneMetrics, after: LaneMetrics) -> float | None:
    """Change of sustained-stop distance between two runs of a lane; None when either did not stop in its window."""
    if not (before.stop.stopped and after.stop.stopped):
        return None
    return after.stop.distance - before.stop.distance


class ColorEffect(BaseModel):
    """What swapping the lanes' Surface colours changed, measured by running both and comparing every array."""

    identical: bool  # every physical array bit-identical
    max_abs_diff: dict[str, float]
    stop_deltas: dict[str, float | None]  # per lane: swapped minus baseline stop distance
    affects_results: bool  # a lane's stop changed status or moved beyond the resolution tolerance
    farther_color: dict[str, str]  # lane -> colour name, for the lanes that went farther when swapped

    def describe(self) -> str:
        if self.identical:
            return "every array of the colour-swapped run is bit-identical to the baseline run"
        diffs = ", ".join(f"{k} {v:.3g}" for k, v in self.max_abs_diff.items() if v)
        stops = ", ".join(f"{lane} {'not comparable' if d is None else f'{d:+.4f} m'}"
                          for lane, d in self.stop_deltas.items())
        return f"arrays differ (max |diff|: {diffs}); stop distance changes: {stops}"


def color_effect(base: FrictionMetrics, swapped: FrictionMetrics, base_arrays: dict, swapped_arrays: dict,
                 lane_colors: dict[str, tuple], *, tol: float) -> ColorEffect:
    """Compare a friction run with its colour-swapped twin (same physics inputs, Surface colours exchanged)."""
    fields = sorted(k for k in base_arrays if k not in FRAME_FIELDS)
    diffs = {k: float(np.max(np.abs(base_arrays[k] - swapped_arrays[k]))) if base_arrays[k].size else 0.0
             for k in fields}
    deltas, farther, affects = {}, {}, False
    for lane, before in base.lanes.items():
        after = swapped.lanes[lane]
        delta = stop_change(before, after)
        deltas[lane] = delta
        if before.stop.stopped != after.stop.stopped:
            affects = True
        elif delta is not None and abs(delta) > tol:
            affects = True
            if delta > 0:
                farther[lane] = color_name(lane_colors[lane])
    return ColorEffect(identical=not any(diffs.values()), max_abs_diff=diffs, stop_deltas=deltas,
                       affects_results=affects, farther_color=farther)


def color_name(rgb) -> str:
    """The lesson's two lane colours by name: blue-dominant or orange (red-dominant)."""
    return "blue" if rgb[2] >= max(rgb[0], rgb[1]) else "orange" if rgb[0] > rgb[2] else "other"
