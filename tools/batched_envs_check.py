"""Why batched cases (one Genesis scene, `n_envs` parallel environments) are off: compare with fresh scenes.

Run: .venv/bin/python -m tools.batched_envs_check
Prints, per case, whether each environment of a 2-environment scene gives the fresh single scene's samples exactly,
or the largest difference. Per-environment table friction is only expressible as a friction *ratio*
(RigidSolver.set_geoms_friction_ratio), so table 0.30 runs as the baseline's 0.50 times 0.6.
Measured on genesis 1.3.3, CPU (2026-11-24): N1 identical in both environments; friction-baseline differs by
9.2e-07 m in the low lane's x in both environments even with no ratio set (n_envs=1: identical); table 0.30 by
ratio differs by 4.4e-06 m. Scene reuse (worker.engine._scene_for) is exact and covers the same variants.
"""

from __future__ import annotations

import numpy as np

from rubric import get_case
from lessons.l03 import scenes
from worker import engine


def _np(tensor) -> np.ndarray:
    return tensor.detach().cpu().numpy()


def contact_z(gs, spec, n_envs: int) -> np.ndarray:
    built = scenes.build_contact(gs, spec, n_envs=n_envs)
    z = np.empty((spec.n_steps, n_envs))
    for i in range(spec.n_steps):
        built.scene.step()
        z[i] = _np(built.bodies[0].get_pos())[:, 2]
    built.scene.destroy()
    return z


def friction_low_x(gs, spec, n_envs: int, table_ratios: list[float] | None) -> np.ndarray:
    built = scenes.build_friction(gs, spec, n_envs=n_envs)
    if table_ratios is not None:
        built.table.set_friction_ratio(np.array(table_ratios).reshape(n_envs, 1), envs_idx=np.arange(n_envs))
    for _ in range(spec.settle_steps):
        built.scene.step()
    for cube in built.bodies:
        cube.set_dofs_velocity(np.tile([spec.initial_speed, 0.0, 0.0, 0.0, 0.0, 0.0], (n_envs, 1)))
    x = np.empty((spec.sample_count, n_envs))
    x[0] = _np(built.bodies[0].get_pos())[:, 0]
    for i in range(1, spec.sample_count):
        built.scene.step()
        x[i] = _np(built.bodies[0].get_pos())[:, 0]
    built.scene.destroy()
    return x


def _verdict(batched: np.ndarray, fresh: np.ndarray) -> str:
    return "identical" if np.array_equal(batched, fresh) else f"max |diff| = {np.abs(batched - fresh).max():.3e} m"


def main() -> None:
    gs = engine.ensure_genesis("cpu", "32", 0)
    fresh = {name: engine.simulate(gs, get_case(name))[0] for name in ("N1", "friction-baseline", "friction-table-0.30")}
    z = contact_z(gs, get_case("N1"), 2)
    for env in range(2):
        print(f"N1, environment {env} of 2: z {_verdict(z[:, env], fresh['N1']['z'])}")
    base = get_case("friction-baseline")
    same = friction_low_x(gs, base, 2, None)
    for env in range(2):
        print(f"friction-baseline, environment {env} of 2: low_x {_verdict(same[:, env], fresh['friction-baseline']['low_x'])}")
    one = friction_low_x(gs, base, 1, None)
    print(f"friction-baseline, n_envs=1: low_x {_verdict(one[:, 0], fresh['friction-baseline']['low_x'])}")
    ratio = get_case("friction-table-0.30").table.friction / base.table.friction
    mixed = friction_low_x(gs, base, 2, [1.0, ratio])
    print(f"friction-table-0.30 by ratio {ratio:g}, environment 1 of 2: low_x "
          f"{_verdict(mixed[:, 1], fresh['friction-table-0.30']['low_x'])}")


if __name__ == "__main__":
    main()
