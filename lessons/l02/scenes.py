"""L02's Genesis scene: a Box dropped onto the ground plane, built and sampled after every outer step
(worker.scene_kit says what a lesson's scenes module provides). Imported only inside a case process, by the runner
(worker.engine), by the name L02's declaration gives; the runner passes the initialised `gs`."""

from __future__ import annotations

import json
import time

import numpy as np

from worker.scene_kit import EMPTY_FRAME, BuiltScene, clock, discretization, frame, strip_fields, to_numpy

from .specs import BOX_RHO, BOX_SIZE_M, BOX_START_Z_M, GRAVITY, DropCase

# What a reused scene sets per case: only how long it is stepped and what the case is called.
PER_CASE_FIELDS = {"name", "duration"}


def structure_key(spec: DropCase) -> str:
    data = spec.model_dump(mode="json", exclude_computed_fields=True)
    if spec.render:
        return "render:" + json.dumps(data, sort_keys=True)
    return json.dumps(strip_fields(data, PER_CASE_FIELDS), sort_keys=True)


def build(gs, spec: DropCase) -> BuiltScene:
    """Declaration and build: the scene, the ground, the box (and a camera when rendering)."""
    scene = gs.Scene(sim_options=gs.options.SimOptions(dt=spec.dt, substeps=spec.substeps, gravity=(0.0, 0.0, -GRAVITY)),
                     show_viewer=False)
    ground = scene.add_entity(gs.morphs.Plane())
    box = scene.add_entity(gs.morphs.Box(size=(BOX_SIZE_M,) * 3, pos=(0.0, 0.0, BOX_START_Z_M)),
                           material=gs.materials.Rigid(rho=BOX_RHO))
    camera = scene.add_camera(res=(320, 240), pos=(1.2, -1.2, 0.9), lookat=(0.0, 0.0, 0.5), fov=40,
                              GUI=False) if spec.render else None
    started = time.perf_counter()
    scene.build()
    return BuiltScene(scene, ground, camera, [box], time.perf_counter() - started)


def simulate(gs, spec: DropCase, built: BuiltScene, scene_path: str):
    """Stepping and observation: one sample of the box after every outer step."""
    scene, ground, camera, box = built.scene, built.table, built.camera, built.bodies[0]
    n = spec.n_steps
    out = {"t": np.empty(n), "z": np.empty(n), "vz": np.empty(n), "contact_count": np.empty(n, dtype=np.int32)}
    frames = {"frame_initial": EMPTY_FRAME, "frame_final": EMPTY_FRAME}
    render_s = 0.0
    if camera is not None:
        started = time.perf_counter()
        frames["frame_initial"] = frame(camera)
        render_s += time.perf_counter() - started
    start = clock(scene)
    stepping = time.perf_counter()
    for i in range(n):
        scene.step()
        out["t"][i] = scene.sim.cur_t - start["t"]
        out["z"][i] = to_numpy(box.get_pos())[2]
        out["vz"][i] = to_numpy(box.get_vel())[2]
        out["contact_count"][i] = int(box.get_contacts(with_entity=ground)["position"].shape[0])
    steps_s = time.perf_counter() - stepping
    window = discretization(scene, start, samples=n)
    if camera is not None:
        started = time.perf_counter()
        frames["frame_final"] = frame(camera)
        render_s += time.perf_counter() - started
    timings = {"build_s": built.build_s if scene_path == "fresh" else 0.0, "steps_s": steps_s, "render_s": render_s}
    return out | frames, timings, window
