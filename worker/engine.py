"""Genesis-side execution of one case: init on the exact backend, build (or reuse) the scene and step it through the
lesson's scenes module, write the evidence.

Imported only inside a case process (worker.isolated_process or worker.warm_process). The only module of the service
that imports `genesis`; a lesson's scenes module (rubric.lesson.Lesson.scenes, worker.scene_kit) is handed the
initialised `gs`. Both execution modes call `run_case_in_genesis`, so they cannot drift into different physics.
"""

from __future__ import annotations

import importlib
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
from types import ModuleType

import numpy as np

from rubric.lesson import lesson_of_kind
from rubric.results import RUNNER_VERSION

from .errors import EXIT_OK, EXIT_PROVENANCE, EXIT_RENDER, ProvenanceError, RenderError
from .kernel_cache import remove_stale_lock
from .scene_kit import BuiltScene

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


# Built scenes kept for reuse, by (scenes module, structure key), least recently used first. Bounded: each holds engine
# fields. An L03 submission alone uses 6 structures (N1-N5, the friction table), so fewer would thrash; with 16 contact
# scenes kept the warm process measured 1.03 GB resident, unchanged over a second round of the same 16 cases.
SCENE_CACHE_MAX = 16
_scenes: "OrderedDict[tuple[str, str], BuiltScene]" = OrderedDict()


def scenes_of(spec) -> ModuleType:
    """The scenes module of the lesson that declares the spec's case kind (rubric.lesson.lesson_of_kind), imported
    here, inside the case process, by the name the declaration gives."""
    return importlib.import_module(lesson_of_kind(spec.kind).scenes)


def _scene_for(gs, scenes: ModuleType, spec, reuse: bool) -> tuple[BuiltScene, str]:
    """A built scene for this case: a kept one of the same structure (the lesson's structure_key), reset to its
    initial state ("reused"), or a new one ("fresh"), kept for later cases when reuse is on."""
    if not reuse:
        return scenes.build(gs, spec), "fresh"
    key = (scenes.__name__, scenes.structure_key(spec))
    built = _scenes.get(key)
    if built is not None:
        _scenes.move_to_end(key)
        built.scene.reset()
        return built, "reused"
    built = scenes.build(gs, spec)
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


def simulate(gs, spec, *, reuse: bool = False):
    """Build (or reuse) the case's scene and step it through its lesson's scenes module: (arrays, timings,
    discretization, scene path "fresh" or "reused")."""
    scenes = scenes_of(spec)
    built, scene_path = _scene_for(gs, scenes, spec, reuse)
    arrays, timings, discretization = scenes.simulate(gs, spec, built, scene_path)
    return arrays, timings, discretization, scene_path


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


def run_case_in_genesis(spec, out_dir: Path, *, mode: str, reuse: bool = False) -> int:
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
