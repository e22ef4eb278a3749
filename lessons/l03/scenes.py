"""L03's Genesis scenes: the contact case (a cube dropped on a table) and the friction case (cubes sliding in lanes
on a table), built and sampled (worker.scene_kit says what a lesson's scenes module provides).

Imported only inside a case process, by the runner (worker.engine), by the name L03's declaration gives
(rubric.l03: scenes). It never imports Genesis itself: the runner passes the initialised `gs`.
"""

from __future__ import annotations

import json
import time

import numpy as np

from rubric import ContactCase, FrictionCase
from worker.scene_kit import EMPTY_FRAME, BuiltScene, clock, discretization, frame, strip_fields, to_numpy

# What a reused scene sets per case instead of building anew: friction coefficients are written into the built
# geometry exactly as a build writes them, names and (unrendered) colours never enter the physics, and the rest only
# shapes the stepping loop or the metrics. Everything else of the spec (dt, substeps, gravity, bodies, sizes,
# positions, density, backend, precision, seed, render) is the structure: a different value builds a new scene.
PER_CASE_FIELDS = {
    "contact": {"name", "duration", "separation_tolerance", "upward_speed_tolerance", "tail_window",
                ("table", "friction"), ("cube", "friction"), ("cube", "color")},
    "friction": {"name", "duration", "settle_steps", "initial_speed", "stop_speed", "hold",
                 ("table", "friction"), ("lanes", "friction"), ("lanes", "name"), ("lanes", "color")},
}


def structure_key(spec: ContactCase | FrictionCase) -> str:
    """The spec less its per-case fields: two cases with one key can share a built scene."""
    data = spec.model_dump(mode="json", exclude_computed_fields=True)
    if spec.render:
        return "render:" + json.dumps(data, sort_keys=True)  # a camera's frames show colours: never shared
    return json.dumps(strip_fields(data, PER_CASE_FIELDS[spec.kind]), sort_keys=True)


def build(gs, spec: ContactCase | FrictionCase, n_envs: int = 0) -> BuiltScene:
    """A new scene for the case, built. n_envs > 0 (parallel environments) only in tools/batched_envs_check.py: off in
    service, arrays not equal."""
    return (build_contact if isinstance(spec, ContactCase) else build_friction)(gs, spec, n_envs)


def simulate(gs, spec: ContactCase | FrictionCase, built: BuiltScene, scene_path: str):
    """Step the built scene and record the case's samples: (arrays, timings, discretization)."""
    return (simulate_contact if isinstance(spec, ContactCase) else simulate_friction)(gs, spec, built, scene_path)


def _scene(gs, spec, camera_view):
    scene = gs.Scene(
        sim_options=gs.options.SimOptions(dt=spec.dt, substeps=spec.substeps, gravity=spec.gravity),
        rigid_options=gs.options.RigidOptions(enable_collision=spec.enable_collision),
        show_viewer=False,
    )
    table = scene.add_entity(
        gs.morphs.Box(size=spec.table.size, pos=spec.table.pos, fixed=True),
        material=gs.materials.Rigid(friction=spec.table.friction),
        surface=gs.surfaces.Default(color=(0.55, 0.45, 0.35)),
    )
    camera = None
    if spec.render:
        pos, lookat = camera_view
        camera = scene.add_camera(res=(480, 320), pos=pos, lookat=lookat, fov=40, GUI=False)
    return scene, table, camera


def contact_friction(scene, geoms_a: range, geoms_b: range) -> float:
    """The sliding friction the engine assigned to the live contacts between two geometry ranges (0.0: no contact).

    Read from the collider's own contact data after a step (genesis 1.3.3 `func_set_contact` writes
    contact_data.friction), so the pair rule is measured rather than recomputed. Contacts of one pair that disagree
    are not averaged away: the largest value is returned and the metrics compare it with the rule.
    """
    collider = scene.sim.rigid_solver.collider
    state = collider._collider_state
    n = int(state.n_contacts.to_numpy()[0])
    if n == 0:
        return 0.0
    # Physical slots of the live contacts, in the collider's logical order (identity unless it sorts or prunes).
    slots = state.contact_sort_idx.to_numpy()[:n, 0] if _collider_sorts(collider) else np.arange(n)
    ga = state.contact_data.geom_a.to_numpy()[slots, 0]
    gb = state.contact_data.geom_b.to_numpy()[slots, 0]
    friction = state.contact_data.friction.to_numpy()[slots, 0]
    in_a = lambda g: (g >= geoms_a.start) & (g < geoms_a.stop)  # noqa: E731
    in_b = lambda g: (g >= geoms_b.start) & (g < geoms_b.stop)  # noqa: E731
    mask = (in_a(ga) & in_b(gb)) | (in_a(gb) & in_b(ga))
    return float(friction[mask].max()) if mask.any() else 0.0


def _collider_sorts(collider) -> bool:
    config = collider._collider_static_config
    return bool(config.has_prunable_contacts or config.spatial_sort_supported)


def _geoms(entity) -> range:
    return range(entity.geom_start, entity.geom_end)


def build_contact(gs, spec: ContactCase, n_envs: int = 0) -> BuiltScene:
    scene, table, camera = _scene(gs, spec, ((1.15, -0.95, 1.05), (0.35, 0.0, 0.78)))
    cube = scene.add_entity(
        gs.morphs.Box(size=(spec.cube.size,) * 3, pos=spec.cube.pos),
        material=gs.materials.Rigid(rho=spec.cube.rho, friction=spec.cube.friction),
        surface=gs.surfaces.Default(color=spec.cube.color),
    )
    t_build = time.perf_counter()
    scene.build(n_envs=n_envs)
    return BuiltScene(scene, table, camera, [cube], time.perf_counter() - t_build)


def simulate_contact(gs, spec: ContactCase, built: BuiltScene, scene_path: str = "fresh"):
    scene, table, camera, cube, build_s = built.scene, built.table, built.camera, built.bodies[0], built.build_s
    if scene_path == "reused":
        table.set_friction(spec.table.friction)
        cube.set_friction(spec.cube.friction)
    n = spec.n_steps
    out = {
        "t": np.empty(n),
        "z": np.empty(n),
        "vz": np.empty(n),
        "contact_count": np.empty(n, dtype=np.int32),
        "quat": np.empty((n, 4)),
    }
    render_s = 0.0
    frames = {"frame_initial": EMPTY_FRAME, "frame_final": EMPTY_FRAME}
    if camera is not None:
        t_r = time.perf_counter()
        frames["frame_initial"] = frame(camera)
        render_s += time.perf_counter() - t_r
    start = clock(scene)
    t_steps = time.perf_counter()
    for i in range(n):
        scene.step()
        # Sample time as the engine counts it (substeps x substep_dt), one sample after every outer step.
        out["t"][i] = scene.sim.cur_t - start["t"]
        out["z"][i] = to_numpy(cube.get_pos())[2]
        out["vz"][i] = to_numpy(cube.get_vel())[2]
        out["quat"][i] = to_numpy(cube.get_quat())
        out["contact_count"][i] = int(cube.get_contacts(with_entity=table)["position"].shape[0])
    steps_s = time.perf_counter() - t_steps
    window = discretization(scene, start, samples=n)
    if camera is not None:
        t_r = time.perf_counter()
        frames["frame_final"] = frame(camera)
        render_s += time.perf_counter() - t_r
    out["clearance"] = out["z"] - spec.cube.size / 2 - spec.table.top_z
    timings = {"build_s": build_s if scene_path == "fresh" else 0.0, "steps_s": steps_s, "render_s": render_s}
    return out | frames, timings, window


def build_friction(gs, spec: FrictionCase, n_envs: int = 0) -> BuiltScene:
    tx = spec.table.pos[0]
    scene, table, camera = _scene(gs, spec, ((tx, -2.0, 1.55), (tx, 0.0, 0.72)))
    cubes = [
        scene.add_entity(
            gs.morphs.Box(size=(spec.cube_size,) * 3, pos=(spec.start_x, lane.y, spec.rest_z)),
            material=gs.materials.Rigid(rho=spec.cube_rho, friction=lane.friction),
            surface=gs.surfaces.Default(color=lane.color),
        )
        for lane in spec.lanes
    ]
    t_build = time.perf_counter()
    scene.build(n_envs=n_envs)
    return BuiltScene(scene, table, camera, cubes, time.perf_counter() - t_build)


def simulate_friction(gs, spec: FrictionCase, built: BuiltScene, scene_path: str = "fresh"):
    scene, table, camera, build_s = built.scene, built.table, built.camera, built.build_s
    # Lanes by position: a reused scene's bodies were added for another case's lane names.
    cubes = {lane.name: body for lane, body in zip(spec.lanes, built.bodies)}
    if scene_path == "reused":
        table.set_friction(spec.table.friction)
        for lane in spec.lanes:
            cubes[lane.name].set_friction(lane.friction)
    t_steps = time.perf_counter()
    # Settle first, so the contact manifold exists before measurement time zero.
    for _ in range(spec.settle_steps):
        scene.step()
    velocity = np.array([spec.initial_speed, 0.0, 0.0, 0.0, 0.0, 0.0])
    for cube in cubes.values():
        cube.set_dofs_velocity(velocity)

    n = spec.sample_count
    out: dict[str, np.ndarray] = {"t": np.empty(n)}
    for lane in spec.lanes:
        p = lane.name
        out |= {f"{p}_{k}": np.empty(n) for k in ("x", "y", "z", "vx", "contact_friction")}
        out[f"{p}_omega"] = np.empty((n, 3))
        # Orientation (w, x, y, z) at every sample: whether a lane's cube tipped over is read from it (rubric.metrics).
        out[f"{p}_quat"] = np.empty((n, 4))
        out[f"{p}_contact_count"] = np.empty(n, dtype=np.int32)
        # Each side's coefficient as the built engine holds it for the geometry, next to the pair value it used.
        out[f"{p}_table_friction"] = np.array(float(table.geoms[0].friction))
        out[f"{p}_cube_friction"] = np.array(float(cubes[p].geoms[0].friction))

    start = clock(scene)

    def sample(i):
        out["t"][i] = scene.sim.cur_t - start["t"]
        for name, cube in cubes.items():
            pos, vel = to_numpy(cube.get_pos()), to_numpy(cube.get_vel())
            out[f"{name}_x"][i], out[f"{name}_y"][i], out[f"{name}_z"][i] = pos[:3]
            out[f"{name}_vx"][i] = vel[0]
            out[f"{name}_omega"][i] = to_numpy(cube.get_ang())
            out[f"{name}_quat"][i] = to_numpy(cube.get_quat())
            out[f"{name}_contact_count"][i] = int(cube.get_contacts(with_entity=table)["position"].shape[0])
            out[f"{name}_contact_friction"][i] = contact_friction(scene, _geoms(cube), _geoms(table))

    render_s = 0.0
    frames = {"frame_initial": EMPTY_FRAME, "frame_final": EMPTY_FRAME}
    sample(0)
    if camera is not None:
        t_r = time.perf_counter()
        frames["frame_initial"] = frame(camera)
        render_s += time.perf_counter() - t_r
    for i in range(1, n):
        scene.step()
        sample(i)
    window = discretization(scene, start, samples=n, settle_steps=spec.settle_steps)
    if camera is not None:
        t_r = time.perf_counter()
        frames["frame_final"] = frame(camera)
        render_s += time.perf_counter() - t_r
    steps_s = time.perf_counter() - t_steps - render_s
    timings = {"build_s": build_s if scene_path == "fresh" else 0.0, "steps_s": steps_s, "render_s": render_s}
    return out | frames, timings, window
