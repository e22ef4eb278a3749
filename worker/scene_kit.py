"""What a lesson's scenes module builds on (rubric.lesson.Lesson.scenes): the built scene it hands back, the engine's
own clock and the discretization read from a built scene, frames, and arrays out of Genesis' tensors.

Imported inside a case process only, by worker.engine and by the lessons' scenes modules (lessons/*/scenes.py). It
imports no Genesis itself: the runner passes the initialised `gs` to the lesson.

A lesson's scenes module provides:
  build(gs, spec) -> BuiltScene                 a new scene for the case, built
  simulate(gs, spec, built, scene_path) -> (arrays, timings, discretization)
                                                step it and record its samples; `scene_path` is "fresh" or "reused"
                                                (a kept scene reset by the runner: set what is per case again)
  structure_key(spec) -> str                    two cases of one key can share a built scene
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .errors import RenderError

EMPTY_FRAME = np.zeros((0, 0, 3), dtype=np.uint8)


@dataclass
class BuiltScene:
    scene: object
    table: object
    camera: object
    bodies: list  # the lesson's bodies, in the order its simulate reads them
    build_s: float


def to_numpy(tensor) -> np.ndarray:
    """A Genesis tensor (or anything array-like) as a flat numpy array."""
    return tensor.detach().cpu().numpy().reshape(-1) if hasattr(tensor, "detach") else np.asarray(tensor).reshape(-1)


def frame(camera) -> np.ndarray:
    """One RGB frame from a Genesis camera; RenderError (the case's exit status says so) when it cannot render."""
    try:
        rgb = camera.render(rgb=True)[0]
    except Exception as exc:
        raise RenderError(f"camera render failed: {exc}") from exc
    return np.ascontiguousarray(np.asarray(rgb), dtype=np.uint8)


def clock(scene) -> dict:
    """The engine's own step, substep and time counters (never the spec's): what the discretization actually was."""
    return {"steps": scene.t, "substeps": scene.sim.cur_substep_global, "t": scene.sim.cur_t}


def discretization(scene, start: dict, *, samples: int, settle_steps: int = 0) -> dict:
    """dt, substeps and the derived quantities of the measurement window, read from the built Genesis scene."""
    end = clock(scene)
    return {
        "dt": float(scene.sim.dt),
        "substeps": int(scene.sim.substeps),
        "substep_dt": float(scene.sim._substep_dt),
        "n_steps": int(end["steps"] - start["steps"]),
        "internal_updates": int(end["substeps"] - start["substeps"]),
        "duration": float(end["t"] - start["t"]),
        "sample_count": int(samples),
        "settle_steps": int(settle_steps),
    }


def strip_fields(data: dict, fields) -> dict:
    """`data` (a spec dumped as JSON) less `fields`: names, or (parent, child) pairs where the parent is an object or a
    list of objects. What a lesson's structure_key leaves out: what a reused scene sets per case."""
    for field in fields:
        if isinstance(field, str):
            data.pop(field, None)
            continue
        parent, child = field
        for item in data[parent] if isinstance(data[parent], list) else [data[parent]]:
            item.pop(child, None)
    return data
