"""Draw concrete scenes and pushes from a scene template's randomisation ranges."""

from __future__ import annotations

import math

import numpy as np
import pymunk

from probaff.sim.geometry import footprint_support, friction_points
from probaff.sim.specs import ObjectSpec
from probaff.sim.tabletop import SceneInstance
from probaff.sim.tabletop_config import SceneSpec, TabletopSpec

__all__ = ["draw_in_range", "object_shape", "sample_scene"]

_CLEARANCE = 0.003  # minimum gap (m) between bodies in a sampled start configuration


def draw_in_range(rng: np.random.Generator, r: tuple[float, float]) -> float:
    """A uniform draw from the range `r` ``(low, high)``.

    A range of one value (``low == high``) gives that value and leaves `rng` as it is, so a
    template that fixes a quantity draws the same sequence for every other one.
    """
    return float(r[0]) if r[0] == r[1] else float(rng.uniform(r[0], r[1]))


def object_shape(
    space: pymunk.Space,
    obj: ObjectSpec,
    pose: tuple[float, float, float] | np.ndarray,
    margin: float,
) -> pymunk.Shape:
    """Add a kinematic footprint of `obj` at world pose (3,) to `space`, grown by `margin` (m).

    A shape query against it finds what lies within `margin` of the object.

    Args:
        space: The space.
        obj: The catalogue object.
        pose: (3,) world ``(x, y, theta)``.
        margin: How much the footprint is grown (m).

    Returns:
        The added shape.
    """
    body = pymunk.Body(body_type=pymunk.Body.KINEMATIC)
    body.position, body.angle = (float(pose[0]), float(pose[1])), float(pose[2])
    if obj.shape == "circle":
        shape: pymunk.Shape = pymunk.Circle(body, obj.radius + margin)
    else:
        shape = pymunk.Poly.create_box(body, obj.size, radius=margin)
    space.add(body, shape)
    return shape


def sample_scene(
    scene: SceneSpec,
    catalogue: dict[str, ObjectSpec],
    world: TabletopSpec,
    rng: np.random.Generator,
) -> SceneInstance | None:
    """Draw one scene and push, or ``None`` if the draw is physically invalid.

    A draw is invalid when an object's centre is off the table or two bodies (objects, walls,
    or the hand at its start pose) overlap. Callers draw again; the arm's reachability is
    checked separately, in one batch, by IK.

    Args:
        scene: The template.
        catalogue: Object catalogue.
        world: The tabletop world (table size, gripper geometry).
        rng: Source of randomness; the draw consumes a fixed pattern of it for a given template.

    Returns:
        A `SceneInstance`, or ``None``.
    """
    first = scene.objects[0]
    objs = [catalogue[first.choices[int(rng.integers(len(first.choices)))]]]
    assert first.x is not None and first.y is not None
    c1 = np.array([draw_in_range(rng, first.x), draw_in_range(rng, first.y)])
    poses = [(c1[0], c1[1], draw_in_range(rng, first.yaw))]
    phi = draw_in_range(rng, scene.push.direction)
    d = np.array([math.cos(phi), math.sin(phi)])
    yp = np.array([-d[1], d[0]])
    offset = draw_in_range(rng, scene.push.lateral_offset)
    gap = draw_in_range(rng, scene.push.start_gap)
    back = footprint_support(objs[0], poses[0][2], -d) + world.gripper.finger_radius + gap
    start = c1 + offset * yp - back * d

    for spec in scene.objects[1:]:
        obj = catalogue[spec.choices[int(rng.integers(len(spec.choices)))]]
        objs.append(obj)
        if spec.in_push_frame:
            assert spec.along is not None and spec.lateral is not None
            c = c1 + draw_in_range(rng, spec.along) * d + draw_in_range(rng, spec.lateral) * yp
            poses.append((c[0], c[1], phi + draw_in_range(rng, spec.yaw)))
        else:
            assert spec.x is not None and spec.y is not None
            x, y = draw_in_range(rng, spec.x), draw_in_range(rng, spec.y)
            poses.append((x, y, draw_in_range(rng, spec.yaw)))

    walls = []
    for w in scene.walls:
        c = c1 + draw_in_range(rng, w.along) * d + draw_in_range(rng, w.lateral) * yp
        a = phi + math.pi / 2 + draw_in_range(rng, w.angle)
        u = 0.5 * w.length * np.array([math.cos(a), math.sin(a)])
        walls.append([*(c - u), *(c + u)])

    K = len(objs)
    mass = np.array([o.mass for o in objs]) * rng.uniform(*scene.mass_scale, size=K)
    mu_g = np.array([o.ground_friction for o in objs]) * rng.uniform(
        *scene.ground_friction_scale, size=K
    )
    mu_c = np.array([o.contact_friction for o in objs]) * rng.uniform(
        *scene.contact_friction_scale, size=K
    )
    v = scene.support_load_variation
    weights = []
    for o in objs:
        load = rng.uniform(
            1.0 - v, 1.0 + v, size=len(friction_points(o, world.physics.friction_grid))
        )
        weights.append(load / load.mean())

    hx, hy = 0.5 * world.table_size[0], 0.5 * world.table_size[1]
    if any(abs(p[0]) > hx or abs(p[1]) > hy for p in poses):
        return None
    space = pymunk.Space()
    shapes = [object_shape(space, o, p, _CLEARANCE) for o, p in zip(objs, poses, strict=True)]
    g = world.gripper
    hand_body = pymunk.Body(body_type=pymunk.Body.KINEMATIC)
    hand_body.position, hand_body.angle = (float(start[0]), float(start[1])), phi
    hand = pymunk.Poly.create_box(
        hand_body, (2 * g.finger_radius, g.push_opening + 2 * g.finger_radius), radius=_CLEARANCE
    )
    space.add(hand_body, hand)
    for x0, y0, x1, y1 in walls:
        space.add(pymunk.Segment(space.static_body, (x0, y0), (x1, y1), 0.01 + _CLEARANCE))
    if any(space.shape_query(s) for s in [*shapes, hand]):
        return None

    return SceneInstance(
        objects=tuple(objs),
        poses=np.array(poses, dtype=float),
        mass=mass,
        ground_friction=mu_g,
        contact_friction=mu_c,
        support_weights=tuple(weights),
        walls=np.array(walls, dtype=float).reshape(-1, 4),
        push_origin=start,
        push_yaw=phi,
        push_distance=scene.push.distance,
    )
