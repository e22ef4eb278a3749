"""L02's metrics, computed once where a case ran from its validated arrays (rubric.lesson: expected_arrays,
case_metrics), and stored with the run."""

from __future__ import annotations

from typing import Literal

import numpy as np
from pydantic import BaseModel

from rubric.results import FRAME_FIELDS

from .specs import DropCase

class DropMetrics(BaseModel):
    kind: Literal["drop"] = "drop"
    case: str
    samples: int  # samples recorded (one after every outer step)
    final_t: float  # the time of the last sample: the simulated time the run covered
    query_t: float  # the sample time asked about (QUERY_T_S), as the engine counted it
    z_at_query: float  # the box centre's height then (m)
    vz_at_query: float  # its vertical velocity then (m/s)
    # The time of the first sample at which the engine reports a contact between the box and the ground; None: none
    first_contact_t: float | None

def expected_arrays(spec: DropCase) -> dict[str, tuple[tuple[int, ...] | None, str]]:
    n = spec.sample_count
    fields = {"t": ((n,), "f"), "z": ((n,), "f"), "vz": ((n,), "f"), "contact_count": ((n,), "i")}
    return fields | {name: (None, "u") for name in FRAME_FIELDS}

def case_metrics(spec: DropCase, arrays) -> DropMetrics:
    i = spec.query_index
    touching = np.flatnonzero(np.asarray(arrays["contact_count"]) > 0)
    t = np.asarray(arrays["t"], dtype=float)
    return DropMetrics(case=spec.name, samples=int(len(t)), final_t=float(t[-1]), query_t=float(t[i]),
                       z_at_query=float(arrays["z"][i]), vz_at_query=float(arrays["vz"][i]),
                       first_contact_t=float(t[touching[0]]) if touching.size else None)
