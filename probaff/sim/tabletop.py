"""The top-down tabletop in pymunk 7.

Objects carry distributed Coulomb friction; a force-limited hand tracks the arm's trajectory.
Units are SI. The table is centred at the world origin; its surface is the plane of the
simulation. Objects slide with Coulomb friction spread over their footprints
(`probaff.sim.friction`). pymunk multiplies the two shapes' friction coefficients at a contact,
so each shape is given the square root of its catalogue coefficient and a contact pair sees the
geometric mean.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pymunk

from probaff._checks import check_count
from probaff.sim.config import ObjectSpec, TabletopSpec
from probaff.sim.friction import add_sliding_body
from probaff.sim.geometry import friction_points, push_frame_effect
from probaff.sim.pusher import TrackedPusher

__all__ = ["PushOutcome", "SceneInstance", "simulate_push"]

_HAND, _WALL, _OBJECT0 = 1, 2, 10
_WALL_RADIUS = 0.01
_WALL_FRICTION = 0.5


@dataclass(frozen=True)
class SceneInstance:
    """One fully specified scene and push, ready to simulate.

    Attributes:
        objects: Catalogue specs of the K objects; object 0 is the pushed one (o1).
        poses: (K, 3) world ``(x, y, theta)`` at the start.
        mass: (K,) masses (kg).
        ground_friction: (K,) Coulomb coefficients against the table.
        contact_friction: (K,) surface coefficients.
        support_weights: Per object, (P_k,) relative normal loads of its friction support
            points (mean 1; see `probaff.sim.geometry.friction_points`): the unknown, uneven
            pressure distribution under a real object.
        walls: (W, 4) fixed wall segments ``(x0, y0, x1, y1)`` in the world.
        push_origin: (2,) world position of the hand at the start (the pushing-frame origin).
        push_yaw: World yaw of z_p (rad).
        push_distance: d_p (m).
    """

    objects: tuple[ObjectSpec, ...]
    poses: np.ndarray
    mass: np.ndarray
    ground_friction: np.ndarray
    contact_friction: np.ndarray
    support_weights: tuple[np.ndarray, ...]
    walls: np.ndarray
    push_origin: np.ndarray
    push_yaw: float
    push_distance: float

    @classmethod
    def nominal(cls, objects: tuple[ObjectSpec, ...] | list[ObjectSpec], poses: np.ndarray,
                push_origin: np.ndarray, push_yaw: float, push_distance: float,
                friction_grid: int, walls: np.ndarray | None = None) -> SceneInstance:
        """A scene with the catalogue's nominal masses and frictions and uniform pressure.

        Args:
            objects: K catalogue objects; the first is the pushed one.
            poses: (K, 3) world ``(x, y, theta)``.
            push_origin: (2,) world start of the hand.
            push_yaw: World yaw of z_p (rad).
            push_distance: d_p (m).
            friction_grid: The world's ``physics.friction_grid`` (a positive integer).
            walls: (W, 4) wall segments, or ``None``.

        Raises:
            InputError: If `friction_grid` is not a positive integer.
        """
        friction_grid = check_count("friction_grid", friction_grid)
        objects = tuple(objects)
        return cls(
            objects=objects,
            poses=np.asarray(poses, dtype=float).reshape(len(objects), 3),
            mass=np.array([o.mass for o in objects]),
            ground_friction=np.array([o.ground_friction for o in objects]),
            contact_friction=np.array([o.contact_friction for o in objects]),
            support_weights=tuple(np.ones(len(friction_points(o, friction_grid)))
                                  for o in objects),
            walls=np.zeros((0, 4)) if walls is None else np.asarray(walls, float).reshape(-1, 4),
            push_origin=np.asarray(push_origin, dtype=float),
            push_yaw=float(push_yaw),
            push_distance=float(push_distance),
        )


@dataclass(frozen=True)
class PushOutcome:
    """What one push did.

    Attributes:
        state_before: (K, 3) world ``(x, y, theta)`` before.
        state_after: (K, 3) world ``(x, y, theta)`` after (theta unwrapped).
        effect: (K, 3) ``(Delta y_p, Delta z_p, Delta theta_p)`` in the pushing frame.
        hand_contact: (K,) the hand touched the object.
        object_contact: (K, K) symmetric; objects i and j touched each other.
        wall_contact: (K,) the object touched a wall.
        fell_off: (K,) the object's centre left the table.
        traj_time: (T,) sample times (s) of the trajectories.
        traj_hand: (T, 3) world ``(x, y, yaw)`` of the hand.
        traj_objects: (T, K, 3) world ``(x, y, theta)`` of the objects.
        hand_lag: Largest distance (m) between the commanded and the actual hand position,
            large when the hand stalls against something it cannot move.
        max_penetration: Deepest overlap (m) between any two bodies at the end.
    """

    state_before: np.ndarray
    state_after: np.ndarray
    effect: np.ndarray
    hand_contact: np.ndarray
    object_contact: np.ndarray
    wall_contact: np.ndarray
    fell_off: np.ndarray
    traj_time: np.ndarray
    traj_hand: np.ndarray
    traj_objects: np.ndarray
    hand_lag: float
    max_penetration: float


def _object_shape(body: pymunk.Body, obj: ObjectSpec) -> pymunk.Shape:
    if obj.shape == "circle":
        return pymunk.Circle(body, obj.radius)
    return pymunk.Poly.create_box(body, obj.size)


def _add_object(space: pymunk.Space, obj: ObjectSpec, scene: SceneInstance, k: int, grid: int,
                gravity: float) -> tuple[pymunk.Body, list[object]]:
    """Add object `k` as a sliding body with friction spread over its footprint."""

    def make_shape(core: pymunk.Body) -> pymunk.Shape:
        shape = _object_shape(core, obj)
        shape.friction = math.sqrt(float(scene.contact_friction[k]))
        shape.elasticity = 0.0
        shape.collision_type = _OBJECT0 + k
        return shape

    return add_sliding_body(space, float(scene.mass[k]), make_shape, tuple(scene.poses[k]),
                            friction_points(obj, grid), scene.support_weights[k],
                            float(scene.ground_friction[k]), gravity)


class _Contacts:
    """Collects which collision-type pairs have touched."""

    def __init__(self, n_objects: int) -> None:
        self.hand = np.zeros(n_objects, dtype=bool)
        self.wall = np.zeros(n_objects, dtype=bool)
        self.objects = np.zeros((n_objects, n_objects), dtype=bool)

    def begin(self, arbiter: pymunk.Arbiter, space: pymunk.Space, data: object) -> None:
        a, b = (s.collision_type for s in arbiter.shapes)
        a, b = min(a, b), max(a, b)
        if b < _OBJECT0:
            return
        j = b - _OBJECT0
        if a == _HAND:
            self.hand[j] = True
        elif a == _WALL:
            self.wall[j] = True
        elif a >= _OBJECT0:
            i = a - _OBJECT0
            self.objects[i, j] = self.objects[j, i] = True


def _pose(body: pymunk.Body) -> tuple[float, float, float]:
    return (body.position.x, body.position.y, body.angle)


def simulate_push(world: TabletopSpec, scene: SceneInstance, hand_path: np.ndarray
                  ) -> PushOutcome:
    """Run one push in a fresh pymunk space.

    Args:
        world: The tabletop world.
        scene: Objects, walls and the push.
        hand_path: (T_c, 3) commanded world ``(x, y, yaw)`` of the hand at each control tick,
            from the arm's joint trajectory (`Arm.trace`). After the last tick the hand holds
            its pose for ``world.settle_time``.

    Returns:
        The push's outcome.
    """
    phys, grip = world.physics, world.gripper
    space = pymunk.Space()
    space.gravity = (0.0, 0.0)
    space.iterations = phys.iterations
    space.collision_slop = phys.collision_slop
    contacts = _Contacts(len(scene.objects))
    space.on_collision(None, None, begin=contacts.begin)

    bodies: list[pymunk.Body] = []
    parts: list[list[object]] = []  # everything to remove when an object falls off the table
    for k, obj in enumerate(scene.objects):
        body, extra = _add_object(space, obj, scene, k, phys.friction_grid, phys.gravity)
        bodies.append(body)
        parts.append(extra)

    for x0, y0, x1, y1 in scene.walls:
        seg = pymunk.Segment(space.static_body, (float(x0), float(y0)), (float(x1), float(y1)),
                             _WALL_RADIUS)
        seg.friction = math.sqrt(_WALL_FRICTION)
        seg.collision_type = _WALL
        space.add(seg)

    half = 0.5 * grip.push_opening

    def make_fingers(hand: pymunk.Body) -> list[pymunk.Shape]:
        fingers = []
        for side in (-1.0, 1.0):
            f = pymunk.Circle(hand, grip.finger_radius, (0.0, side * half))
            f.friction = math.sqrt(grip.contact_friction)
            f.collision_type = _HAND
            fingers.append(f)
        return fingers

    pusher = TrackedPusher(space, hand_path[0], grip.mass,
                           pymunk.moment_for_box(grip.mass, (2 * grip.finger_radius,
                                                             grip.push_opening)),
                           make_fingers, grip.max_force, grip.max_torque, grip.max_speed)
    hand = pusher.body

    rate = phys.control_rate
    dt = 1.0 / rate / phys.substeps
    n_settle = round(world.settle_time * rate)
    path = np.concatenate([hand_path, np.repeat(hand_path[-1:], n_settle + 1, axis=0)])
    every = max(1, round(rate / world.record_rate))
    hx, hy = 0.5 * world.table_size[0], 0.5 * world.table_size[1]

    K = len(bodies)
    before = np.array([_pose(b) for b in bodies])
    frozen: list[tuple[float, float, float] | None] = [None] * K
    t_rec, hand_rec, obj_rec = [], [], []
    lag = 0.0

    def record(t: float) -> None:
        t_rec.append(t)
        hand_rec.append(_pose(hand))
        obj_rec.append([frozen[k] or _pose(b) for k, b in enumerate(bodies)])

    record(0.0)
    for i in range(len(path) - 1):
        pusher.command(path[i], path[i + 1], rate)
        for _ in range(phys.substeps):
            space.step(dt)
        lag = max(lag, pusher.lag(path[i + 1]))
        for k, b in enumerate(bodies):
            if frozen[k] is None and (abs(b.position.x) > hx or abs(b.position.y) > hy):
                frozen[k] = _pose(b)  # its centre passed the edge: it tips over and falls
                space.remove(*parts[k])
        if (i + 1) % every == 0:
            record((i + 1) / rate)
    if (len(path) - 1) % every:
        record((len(path) - 1) / rate)

    after = np.array([frozen[k] or _pose(b) for k, b in enumerate(bodies)])
    fell = np.array([f is not None for f in frozen])
    return PushOutcome(
        state_before=before,
        state_after=after,
        effect=push_frame_effect(before, after, scene.push_yaw),
        hand_contact=contacts.hand,
        object_contact=contacts.objects,
        wall_contact=contacts.wall,
        fell_off=fell,
        traj_time=np.array(t_rec),
        traj_hand=np.array(hand_rec),
        traj_objects=np.array(obj_rec),
        hand_lag=lag,
        max_penetration=_max_penetration(space),
    )


def _max_penetration(space: pymunk.Space) -> float:
    deepest = 0.0
    for shape in space.shapes:
        if shape.collision_type < _OBJECT0:
            continue
        for hit in space.shape_query(shape):
            for p in hit.contact_point_set.points:
                deepest = max(deepest, -p.distance)
    return deepest
