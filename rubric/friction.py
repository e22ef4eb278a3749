"""The effective sliding-friction value of a contact pair, as the pinned engine computes it.

genesis-world 1.3.3, genesis/engine/solvers/rigid/collider/contact.py (`func_set_contact`):

    friction_a = geoms.friction[i_ga] * geoms.friction_ratio[i_ga, i_b]
    friction_b = geoms.friction[i_gb] * geoms.friction_ratio[i_gb, i_b]
    contact_data.friction = max(max(friction_a, friction_b), 1e-2)

So the lesson's `max(table, cube)` is the common case; the edge cases are the runtime friction ratios (applied to
each side before the max) and a floor of 0.01 on the result. The floor is reachable only through ratios, because
Genesis rejects a material friction below 0.01 (genesis/engine/materials/rigid.py).
"""

from __future__ import annotations

PAIR_FRICTION_FLOOR = 1e-2


def effective_pair_friction(
    friction_a: float, friction_b: float, *, ratio_a: float = 1.0, ratio_b: float = 1.0
) -> float:
    """Sliding friction Genesis 1.3.3 uses for a contact between geometries a and b."""
    return max(max(friction_a * ratio_a, friction_b * ratio_b), PAIR_FRICTION_FLOOR)
