"""Rigid bodies sliding on a floor with Coulomb friction spread over their footprint (pymunk).

A body is a rigid core carrying its collision shape, pinned to P point-mass "feet" at support
points of the footprint. Each foot is held to the floor by a pivot joint whose force is limited
to w_i mu m g / P, w_i being the relative normal load of support point i (all 1 for a uniform
pressure). Because a foot's effective mass is isotropic, the friction impulse at each support
point opposes that point's sliding velocity, which is Coulomb's law; a force-limited joint on
the core itself would couple translation and rotation through the core's inertia and misdirect
the friction. This discretises the limit surface (Goyal et al.); a body stops as soon as
nothing pushes it. The core holds 20 % of the mass and the feet the rest, so the assembly's
inertia approximates a uniform slab.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pymunk

__all__ = ["add_sliding_body"]

_CORE_MASS_FRACTION = 0.2


def add_sliding_body(space: pymunk.Space, mass: float,
                     make_shape: Callable[[pymunk.Body], pymunk.Shape],
                     pose: tuple[float, float, float], support: np.ndarray,
                     weights: np.ndarray, mu: float, gravity: float
                     ) -> tuple[pymunk.Body, list[object]]:
    """Add a sliding body to `space`.

    Args:
        space: The pymunk space (its static body is the floor).
        mass: Total mass (kg).
        make_shape: ``make_shape(core)`` creates the collision shape (centred on the body's
            origin) on the core and returns it; the core's mass and moment follow from it.
        pose: World ``(x, y, theta)``.
        support: (P, 2) support points in the body frame (m).
        weights: (P,) relative normal loads (mean 1).
        mu: Coulomb coefficient against the floor.
        gravity: Gravitational acceleration (m/s^2).

    Returns:
        ``(core, parts)``: the core body, and every body, shape and joint added (to remove the
        body again).
    """
    if len(weights) != len(support):
        raise ValueError(f"{len(weights)} support weights for {len(support)} support points.")
    m_core = _CORE_MASS_FRACTION * mass
    m_foot = (mass - m_core) / len(support)
    core = pymunk.Body()
    shape = make_shape(core)
    shape.mass = m_core
    core.position = (float(pose[0]), float(pose[1]))
    core.angle = float(pose[2])
    added: list[object] = [core, shape]
    limit = mu * mass * gravity / len(support)
    for p, w in zip(support, weights, strict=True):
        local = (float(p[0]), float(p[1]))
        foot = pymunk.Body(m_foot, 1e-9)
        foot.position = core.local_to_world(local)
        pin = pymunk.PivotJoint(core, foot, local, (0.0, 0.0))
        hold = pymunk.PivotJoint(space.static_body, foot, foot.position, (0.0, 0.0))
        hold.max_bias = 0.0
        hold.max_force = limit * float(w)
        added += [foot, pin, hold]
    space.add(*added)
    return core, added
