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

from probaff._checks import check_finite, check_positive, check_shape
from probaff.errors import InputError

__all__ = ["Part", "add_sliding_body"]

_CORE_MASS_FRACTION = 0.2


Part = pymunk.Body | pymunk.Shape | pymunk.Constraint
"""Anything added to a pymunk space."""


def add_sliding_body(
    space: pymunk.Space,
    mass: float,
    make_shape: Callable[[pymunk.Body], pymunk.Shape],
    pose: tuple[float, float, float],
    support: np.ndarray,
    weights: np.ndarray,
    mu: float,
    gravity: float,
) -> tuple[pymunk.Body, list[Part]]:
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

    Raises:
        InputError: For a mass or gravity <= 0, a negative or non-finite friction, pose,
            support point or weight, or a weight count other than the support points';
            checked before anything is added to `space`.
    """
    check_positive("mass", mass)
    check_positive("mu", mu, allow_zero=True)
    check_positive("gravity", gravity)
    check_shape("pose", np.asarray(pose, dtype=float), (3,))
    check_finite("pose", np.asarray(pose, dtype=float))
    support = np.asarray(support, dtype=float)
    weights = np.asarray(weights, dtype=float)
    check_shape("support", support, (None, 2))
    check_finite("support", support)
    check_finite("weights", weights)
    if len(support) == 0:
        raise InputError("support is empty; give at least one (x, y) support point.")
    if len(weights) != len(support):
        raise InputError(
            f"{len(weights)} support weights for {len(support)} support points; build the "
            "weights for friction_points(obj, world.physics.friction_grid)."
        )
    if weights.min() < 0:
        raise InputError(f"weights must be >= 0 (relative normal loads), got {weights.min()}.")
    m_core = _CORE_MASS_FRACTION * mass
    m_foot = (mass - m_core) / len(support)
    core = pymunk.Body()
    shape = make_shape(core)
    shape.mass = m_core
    core.position = (float(pose[0]), float(pose[1]))
    core.angle = float(pose[2])
    added: list[Part] = [core, shape]
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
