"""Genesis-side execution of one case: init on the exact backend, build, step, sample, render, write evidence.

Imported only inside a case process (worker.isolated_process or worker.warm_process). The only module that touches
`genesis`. Both execution modes call `run_case_in_genesis`, so they cannot drift into different physics.
"""

from __future__ import annotations

import json
import os
import platform
import re
import sys
import time
from collections import OrderedDict
from dataclasses import dataclass
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path

import numpy as np

from rubric import ContactCase, FrictionCase
from rubric.results import RUNNER_VERSION

from .errors import EXIT_OK, EXIT_PROVENANCE, EXIT_RENDER, ProvenanceError, RenderError
from .kernel_cache import remove_stale_lock

# Requested backend -> the Genesis backend asked for explicitly. Never gs.gpu: in 1.3.3 it falls back to CPU
# with only a warning (genesis/__init__.py, init).
GENESIS_BACKENDS = {"cpu": "cpu", "rocm": "amdgpu", "cuda": "cuda"}

_state: dict = {"key": None, "import_s": 0.0, "init_s": 0.0}


def ensure_genesis(backend: str, precision: str, seed: int):
    """Genesis initialised for exactly this (backend, precision, seed), re-initialising a warm process if needed."""
    t0 = time.perf_counter()
    if _state["key"] is None:
        remove_stale_lock()
    import genesis as gs  # lazy: only inside a case process, after the stale lock is gone; timed as import_s

    if _state["key"] is None:
        _state["import_s"] = time.perf_counter() - t0
    key = (backend, precision, seed)
    if _state["key"] != key:
        if _state["key"] is not None:
            drop_scenes()
            gs.destroy()
            _state.pop("device_name", None)
        t1 = time.perf_counter()
        try:
            gs.init(
                backend=getattr(gs, GENESIS_BACKENDS[backend]),
                precision=precision,
                seed=seed,
                logging_level="warning",
            )
        except Exception as exc:  # Genesis raises GenesisException when the device is absent
            detail = re.sub(r"~+<|>~+", "", str(exc))  # Genesis's terminal colour markup
            raise ProvenanceError(
                f"requested backend '{backend}' (gs.{GENESIS_BACKENDS[backend]}) could not be initialised: {detail}"
            ) from exc
        _state["init_s"] = time.perf_counter() - t1
        _state["key"] = key
    verify_backend(backend)
    return gs


def verify_backend(requested: str) -> None:
    """Fail visibly unless the initialised backend is the requested one (and ROCm really is a HIP build)."""
    # lazy: Genesis and torch load only inside a case process, never in a parent importing this module
    import genesis as gs
    import torch

    actual = gs.backend.name
    if actual != GENESIS_BACKENDS[requested]:
        raise ProvenanceError(f"requested backend '{requested}' but Genesis initialised '{actual}'")
    # ROCm devices appear in torch's cuda namespace: only torch.version.hip tells them apart from NVIDIA.
    if requested == "rocm" and not torch.version.hip:
        raise ProvenanceError("requested backend 'rocm' but torch is not a ROCm (HIP) build")
    if requested == "cuda" and (torch.version.hip or not torch.version.cuda):
        raise ProvenanceError("requested backend 'cuda' but torch is not a CUDA build")


def _np(tensor) -> np.ndarray:
    return tensor.detach().cpu().numpy().reshape(-1) if hasattr(tensor, "detach") else np.asarray(tensor).reshape(-1)


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


def _frame(camera) -> np.ndarray:
    try:
        rgb = camera.render(rgb=True)[0]
    except Exception as exc:
        raise RenderError(f"camera render failed: {exc}") from exc
    return np.ascontiguousarray(np.asarray(rgb), dtype=np.uint8)


EMPTY_FRAME = np.zeros((0, 0, 3), dtype=np.uint8)


def _clock(scene) -> dict:
    """The engine's own step, substep and time counters (never the spec's): what the discretization actually was."""
    return {"steps": scene.t, "substeps": scene.sim.cur_substep_global, "t": scene.sim.cur_t}


def _discretization(scene, start: dict, *, samples: int, settle_steps: int = 0) -> dict:
    """dt, substeps and the derived quantities of the measurement window, read from the built Genesis scene."""
    end = _clock(scene)
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


@dataclass
class BuiltScene:
    scene: object
    table: object
    camera: object
    bodies: list  # the contact case's cube, or the friction case's lane cubes in lane order
    build_s: float


# Built scenes kept for reuse, by structure key, least recently used first. Bounded: each holds engine fields. A
# submission alone uses 6 structures (N1-N5, the friction table), so fewer would thrash; with 16 contact scenes kept
# the warm process measured 1.03 GB resident, unchanged over a second round of the same 16 cases.
SCENE_CACHE_MAX = 16
_scenes: "OrderedDict[str, BuiltScene]" = OrderedDict()

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
    for field in PER_CASE_FIELDS[spec.kind]:
        if isinstance(field, str):
            data.pop(field, None)
            continue
        parent, child = field
        for item in data[parent] if isinstance(data[parent], list) else [data[parent]]:
            item.pop(child, None)
    return json.dumps(data, sort_keys=True)


def _scene_for(gs, spec, reuse: bool) -> tuple[BuiltScene, str]:
    """A built scene for this case: a kept one of the same structure, reset to its initial state ("reused"), or a
    new one ("fresh"), kept for later cases when reuse is on."""
    build = _build_contact if isinstance(spec, ContactCase) else _build_friction
    if not reuse:
        return build(gs, spec), "fresh"
    key = structure_key(spec)
    built = _scenes.get(key)
    if built is not None:
        _scenes.move_to_end(key)
        built.scene.reset()
        return built, "reused"
    built = build(gs, spec)
    _scenes[key] = built
    while len(_scenes) > SCENE_CACHE_MAX:
        _, old = _scenes.popitem(last=False)
        old.scene.destroy()
    return built, "fresh"


def drop_scenes() -> None:
    """Forget every kept scene (before Genesis is re-initialised, or after a failed case)."""
    while _scenes:
        _, old = _scenes.popitem()
        old.scene.destroy()


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


def _build_contact(gs, spec: ContactCase, n_envs: int = 0) -> "BuiltScene":
    scene, table, camera = _scene(gs, spec, ((1.15, -0.95, 1.05), (0.35, 0.0, 0.78)))
    cube = scene.add_entity(
        gs.morphs.Box(size=(spec.cube.size,) * 3, pos=spec.cube.pos),
        material=gs.materials.Rigid(rho=spec.cube.rho, friction=spec.cube.friction),
        surface=gs.surfaces.Default(color=spec.cube.color),
    )
    t_build = time.perf_counter()
    # n_envs > 0 (parallel environments) only in tools/batched_envs_check.py: off in service, arrays not equal.
    scene.build(n_envs=n_envs)
    return BuiltScene(scene, table, camera, [cube], time.perf_counter() - t_build)


def simulate_contact(gs, spec: ContactCase, *, reuse: bool = False):
    built, scene_path = _scene_for(gs, spec, reuse)
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
        frames["frame_initial"] = _frame(camera)
        render_s += time.perf_counter() - t_r
    start = _clock(scene)
    t_steps = time.perf_counter()
    for i in range(n):
        scene.step()
        # Sample time as the engine counts it (substeps x substep_dt), one sample after every outer step.
        out["t"][i] = scene.sim.cur_t - start["t"]
        out["z"][i] = _np(cube.get_pos())[2]
        out["vz"][i] = _np(cube.get_vel())[2]
        out["quat"][i] = _np(cube.get_quat())
        out["contact_count"][i] = int(cube.get_contacts(with_entity=table)["position"].shape[0])
    steps_s = time.perf_counter() - t_steps
    discretization = _discretization(scene, start, samples=n)
    if camera is not None:
        t_r = time.perf_counter()
        frames["frame_final"] = _frame(camera)
        render_s += time.perf_counter() - t_r
    out["clearance"] = out["z"] - spec.cube.size / 2 - spec.table.top_z
    timings = {"build_s": build_s if scene_path == "fresh" else 0.0, "steps_s": steps_s, "render_s": render_s}
    return out | frames, timings, discretization, scene_path


def _build_friction(gs, spec: FrictionCase, n_envs: int = 0) -> "BuiltScene":
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
    # n_envs > 0 (parallel environments) only in tools/batched_envs_check.py: off in service, arrays not equal.
    scene.build(n_envs=n_envs)
    return BuiltScene(scene, table, camera, cubes, time.perf_counter() - t_build)


def simulate_friction(gs, spec: FrictionCase, *, reuse: bool = False):
    built, scene_path = _scene_for(gs, spec, reuse)
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

    start = _clock(scene)

    def sample(i):
        out["t"][i] = scene.sim.cur_t - start["t"]
        for name, cube in cubes.items():
            pos, vel = _np(cube.get_pos()), _np(cube.get_vel())
            out[f"{name}_x"][i], out[f"{name}_y"][i], out[f"{name}_z"][i] = pos[:3]
            out[f"{name}_vx"][i] = vel[0]
            out[f"{name}_omega"][i] = _np(cube.get_ang())
            out[f"{name}_quat"][i] = _np(cube.get_quat())
            out[f"{name}_contact_count"][i] = int(cube.get_contacts(with_entity=table)["position"].shape[0])
            out[f"{name}_contact_friction"][i] = contact_friction(scene, _geoms(cube), _geoms(table))

    render_s = 0.0
    frames = {"frame_initial": EMPTY_FRAME, "frame_final": EMPTY_FRAME}
    sample(0)
    if camera is not None:
        t_r = time.perf_counter()
        frames["frame_initial"] = _frame(camera)
        render_s += time.perf_counter() - t_r
    for i in range(1, n):
        scene.step()
        sample(i)
    discretization = _discretization(scene, start, samples=n, settle_steps=spec.settle_steps)
    if camera is not None:
        t_r = time.perf_counter()
        frames["frame_final"] = _frame(camera)
        render_s += time.perf_counter() - t_r
    steps_s = time.perf_counter() - t_steps - render_s
    timings = {"build_s": build_s if scene_path == "fresh" else 0.0, "steps_s": steps_s, "render_s": render_s}
    return out | frames, timings, discretization, scene_path


def _provenance(spec, mode: str, timings: dict, discretization: dict, rendering: dict, exit_status: int) -> dict:
    # lazy: Genesis and torch load only inside a case process, never in a parent importing this module
    import genesis as gs
    import torch

    device = gs.device
    if "device_name" not in _state:
        from genesis.utils.misc import get_device  # lazy: Genesis only inside a case process

        # Genesis's own probe: the CPU brand string on cpu, the device properties' name on a GPU.
        _state["device_name"] = str(get_device(gs.backend)[1])
    device_name = _state["device_name"]
    return {
        "case": spec.name,
        "requested_backend": spec.backend,
        "actual_backend": {v: k for k, v in GENESIS_BACKENDS.items()}.get(gs.backend.name, gs.backend.name),
        "torch_device": str(device),
        "device_name": device_name,
        "torch_hip": torch.version.hip,
        "torch_cuda": torch.version.cuda,
        "versions": {
            "genesis": _dist_version("genesis-world"),
            "quadrants": _dist_version("quadrants"),
            "torch": torch.__version__,
            "numpy": np.__version__,
            "python": platform.python_version(),
        },
        "precision": spec.precision,
        "seed": spec.seed,
        "deterministic_algorithms": bool(torch.are_deterministic_algorithms_enabled()),
        "execution_mode": mode,
        "host": platform.node(),
        "pid": os.getpid(),
        "timings": {"import_s": _state["import_s"], "init_s": _state["init_s"], **timings},
        "discretization": discretization,
        "rendering": rendering,
        "runner_version": RUNNER_VERSION,
        "exit_status": exit_status,
    }


def _dist_version(name: str) -> str:
    try:
        return version(name)
    except PackageNotFoundError:
        return "absent"


def run_case_in_genesis(spec: ContactCase | FrictionCase, out_dir: Path, *, mode: str, reuse: bool = False) -> int:
    """Run one case and write arrays.npz + provenance.json into out_dir. Returns the process exit status.

    reuse (warm case processes only): a scene already built for this structure is reset and reused; the provenance
    says which ("fresh" or "reused").

    On failure nothing is written but the error on stderr: no arrays, so no partial result can be mistaken for one.
    """
    out_dir = Path(out_dir)
    try:
        if spec.render:
            # Headless rendering goes through EGL with Mesa; osmesa did not load on the course machines.
            os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
        gs = ensure_genesis(spec.backend, spec.precision, spec.seed)
        simulate = simulate_contact if isinstance(spec, ContactCase) else simulate_friction
        arrays, timings, discretization, scene_path = simulate(gs, spec, reuse=reuse)
    except ProvenanceError as exc:
        print(f"PROVENANCE ERROR [{spec.name}]: {exc}", file=sys.stderr, flush=True)
        return EXIT_PROVENANCE
    except RenderError as exc:
        print(f"RENDER ERROR [{spec.name}]: {exc}", file=sys.stderr, flush=True)
        return EXIT_RENDER
    rendering = (
        {"requested": True, "status": "OK", "frames": 2, "detail": "initial and final RGB frames from a Genesis camera"}
        if spec.render
        else {"requested": False, "status": "SKIP", "frames": 0, "detail": "rendering disabled; frame fields empty"}
    )
    if not spec.render:
        print(f"rendering SKIP [{spec.name}]: rendering disabled, frame fields are empty", flush=True)
    provenance = _provenance(spec, mode, timings, discretization, rendering, EXIT_OK) | {"scene": scene_path}
    tmp = out_dir / "arrays.tmp.npz"
    np.savez(tmp, **arrays)
    (out_dir / "provenance.json").write_text(json.dumps(provenance, indent=2))
    # Arrays appear under their final name only once complete.
    tmp.replace(out_dir / "arrays.npz")
    print(
        f"case {spec.name}: backend={provenance['actual_backend']} samples={spec.sample_count} "
        f"scene={scene_path} build={timings['build_s']:.2f}s steps={timings['steps_s']:.2f}s",
        flush=True,
    )
    return EXIT_OK
