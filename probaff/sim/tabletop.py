"""The top-down tabletop in pymunk 7.

Objects carry distributed Coulomb friction; a force-limited hand tracks the arm's trajectory,
stiffly or through a Cartesian impedance (``hand`` in ``worlds/tabletop.yaml``,
`probaff.sim.pusher.HandSpec`), and records its deviation from the command (the reaction).
Units are SI. The table is centred at the world origin; its surface is the plane of the
simulation. Objects slide with Coulomb friction spread over their footprints
(`probaff.sim.friction`). pymunk multiplies the two shapes' friction coefficients at a contact,
so each shape is given the square root of its catalogue coefficient and a contact pair sees the
geometric mean.

The module registers the ``tabletop`` world kind (`probaff.sim.registry`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pymunk

from probaff._checks import check_count, check_finite, check_positive, check_shape, real_float64
from probaff.errors import InputError
from probaff.sim.friction import Part, add_sliding_body
from probaff.sim.geometry import (
    body_pose,
    contact_depth,
    footprint_penetration,
    friction_points,
    push_frame_effect,
)
from probaff.sim.inputs import check_objects, check_type, numeric_fields
from probaff.sim.pusher import TrackedPusher
from probaff.sim.registry import WorldKind, register_world
from probaff.sim.specs import ObjectSpec
from probaff.sim.tabletop_config import SCENES, TabletopSpec, load_scene, load_tabletop

__all__ = ["PushOutcome", "SceneInstance", "simulate_push"]

_HAND, _WALL, _OBJECT0 = 1, 2, 10
_WALL_RADIUS = 0.01
_WALL_FRICTION = 0.5
_OVERLAP = 0.01  # deeper interpenetration (m) of two footprints at the start is a wrong pose;
# the physics itself leaves an object pushed against another a few millimetres into it


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

    def __post_init__(self) -> None:
        objects = check_objects("SceneInstance", self.objects, "load_catalogue()")
        object.__setattr__(self, "objects", objects)
        numeric_fields(
            self,
            ("poses", "mass", "ground_friction", "contact_friction", "walls", "push_origin"),
        )
        if not isinstance(self.support_weights, (tuple, list)):
            raise InputError(
                "SceneInstance.support_weights must be a tuple of one (P_k,) array per object, "
                f"got {type(self.support_weights).__name__}."
            )
        object.__setattr__(
            self, "support_weights", tuple(np.asarray(w, dtype=float) for w in self.support_weights)
        )
        self.validate()

    def validate(self) -> None:
        """Check every physical parameter, so that nothing invalid reaches pymunk.

        Runs on construction, and again before a push is simulated (the arrays are mutable).

        Raises:
            InputError: Naming the field, for a wrong shape, a NaN or infinite value, a mass
                or push distance <= 0, a negative friction or support load, or two objects
                whose footprints overlap by more than 1 cm (objects pushed against each
                other interpenetrate slightly in the physics).
        """
        K = len(self.objects)
        for name, shape in (
            ("poses", (K, 3)),
            ("mass", (K,)),
            ("ground_friction", (K,)),
            ("contact_friction", (K,)),
            ("walls", (None, 4)),
            ("push_origin", (2,)),
        ):
            check_shape(f"SceneInstance.{name}", getattr(self, name), shape)
            check_finite(f"SceneInstance.{name}", getattr(self, name))
        for k in range(K):
            check_positive(f"SceneInstance.mass[{k}]", float(self.mass[k]))
            check_positive(
                f"SceneInstance.ground_friction[{k}]",
                float(self.ground_friction[k]),
                allow_zero=True,
            )
            check_positive(
                f"SceneInstance.contact_friction[{k}]",
                float(self.contact_friction[k]),
                allow_zero=True,
            )
        if len(self.support_weights) != K:
            raise InputError(
                f"SceneInstance.support_weights has {len(self.support_weights)} entries for {K} "
                "objects; give one (P_k,) array of relative loads per object."
            )
        for k, w in enumerate(self.support_weights):
            check_shape(f"SceneInstance.support_weights[{k}]", w, (None,))
            check_finite(f"SceneInstance.support_weights[{k}]", w)
            if len(w) == 0 or w.min() < 0:
                raise InputError(
                    f"SceneInstance.support_weights[{k}] must be a non-empty array of loads "
                    ">= 0 (mean 1); build it with np.ones(len(friction_points(obj, grid)))."
                )
        check_finite("SceneInstance.push_yaw", self.push_yaw)
        check_positive("SceneInstance.push_distance", self.push_distance)
        for i in range(K):
            for j in range(i + 1, K):
                depth = footprint_penetration(
                    self.objects[i], self.poses[i], self.objects[j], self.poses[j]
                )
                if depth > _OVERLAP:
                    raise InputError(
                        f"SceneInstance.poses: objects {i} ({self.objects[i].name}) and {j} "
                        f"({self.objects[j].name}) overlap by {1000 * depth:.1f} mm at the "
                        "start; move them apart."
                    )

    def check_on_table(self, world: TabletopSpec) -> None:
        """Raise `InputError` unless every object's centre lies on the world's table.

        Args:
            world: The tabletop world (its table size).
        """
        hx, hy = 0.5 * world.table_size[0], 0.5 * world.table_size[1]
        for k, (x, y, _) in enumerate(self.poses):
            if abs(x) > hx or abs(y) > hy:
                raise InputError(
                    f"SceneInstance.poses[{k}] puts {self.objects[k].name!r}'s centre at "
                    f"({x:.3f}, {y:.3f}) m, off the {2 * hx:g} x {2 * hy:g} m table centred at "
                    "the origin; place it on the table."
                )

    @classmethod
    def nominal(
        cls,
        objects: tuple[ObjectSpec, ...] | list[ObjectSpec],
        poses: np.ndarray,
        push_origin: np.ndarray,
        push_yaw: float,
        push_distance: float,
        friction_grid: int,
        walls: np.ndarray | None = None,
    ) -> SceneInstance:
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
            poses=_rows_of_three(poses, len(objects)),
            mass=np.array([o.mass for o in objects]),
            ground_friction=np.array([o.ground_friction for o in objects]),
            contact_friction=np.array([o.contact_friction for o in objects]),
            support_weights=tuple(np.ones(len(friction_points(o, friction_grid))) for o in objects),
            walls=np.zeros((0, 4)) if walls is None else np.asarray(walls, float).reshape(-1, 4),
            push_origin=np.asarray(push_origin, dtype=float),
            push_yaw=float(push_yaw),
            push_distance=float(push_distance),
        )


def _rows_of_three(poses: np.ndarray, k: int) -> np.ndarray:
    """`poses` as (k, 3) when it holds 3 k numbers; otherwise unchanged, for the shape check."""
    arr = np.asarray(poses, dtype=float)
    return arr.reshape(k, 3) if arr.size == 3 * k else arr


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
        traj_commanded: (T, 3) commanded world ``(x, y, yaw)`` of the hand at `traj_time`.
        reaction: (R, 3) the hand's deviation from its commanded pose, actual minus
            commanded, in the pushing frame ``(Delta y_p, Delta z_p, Delta theta)``, at R =
            ``world.hand.reaction_samples`` times evenly spaced from the start of the push to
            the end of the settling (the thesis's reaction, along the path).
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
    traj_commanded: np.ndarray
    reaction: np.ndarray


def _object_shape(body: pymunk.Body, obj: ObjectSpec) -> pymunk.Shape:
    if obj.shape == "circle":
        return pymunk.Circle(body, obj.radius)
    return pymunk.Poly.create_box(body, obj.size)


def _add_object(
    space: pymunk.Space, obj: ObjectSpec, scene: SceneInstance, k: int, grid: int, gravity: float
) -> tuple[pymunk.Body, list[Part]]:
    """Add object `k` as a sliding body with friction spread over its footprint."""

    def make_shape(core: pymunk.Body) -> pymunk.Shape:
        shape = _object_shape(core, obj)
        shape.friction = math.sqrt(float(scene.contact_friction[k]))
        shape.elasticity = 0.0
        shape.collision_type = _OBJECT0 + k
        return shape

    return add_sliding_body(
        space,
        float(scene.mass[k]),
        make_shape,
        tuple(scene.poses[k]),
        friction_points(obj, grid),
        scene.support_weights[k],
        float(scene.ground_friction[k]),
        gravity,
    )


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


def _check_push(world: object, scene: object, hand_path: object) -> np.ndarray:
    """`hand_path` as a finite (T_c, 3) array, after checking the world and the scene."""
    world = check_type("world", world, TabletopSpec, "load_tabletop()")
    scene = check_type("scene", scene, SceneInstance, "see sample_scene or SceneInstance.nominal")
    scene.validate()
    scene.check_on_table(world)
    path = real_float64(hand_path)
    if path is None:
        raise InputError(f"hand_path must be a (T_c, 3) numeric array, got {hand_path!r}.")
    check_shape("hand_path", path, (None, 3))
    if len(path) == 0:
        raise InputError("hand_path is empty; give at least one (x, y, yaw) control tick.")
    check_finite("hand_path", path)
    return path


def _build(
    world: TabletopSpec, scene: SceneInstance, start: np.ndarray
) -> tuple[pymunk.Space, _Contacts, list[pymunk.Body], list[list[Part]], TrackedPusher]:
    """A fresh space holding the objects, the walls and the hand at pose `start` (3,).

    Returns:
        ``(space, contacts, bodies, parts, pusher)``: `parts` holds, per object, everything to
        remove when it falls off the table.
    """
    phys, grip = world.physics, world.gripper
    space = pymunk.Space()
    space.gravity = (0.0, 0.0)
    space.iterations = phys.iterations
    space.collision_slop = phys.collision_slop
    space.collision_bias = phys.collision_bias
    contacts = _Contacts(len(scene.objects))
    space.on_collision(None, None, begin=contacts.begin)

    bodies: list[pymunk.Body] = []
    parts: list[list[Part]] = []
    for k, obj in enumerate(scene.objects):
        body, extra = _add_object(space, obj, scene, k, phys.friction_grid, phys.gravity)
        bodies.append(body)
        parts.append(extra)

    for x0, y0, x1, y1 in scene.walls:
        seg = pymunk.Segment(
            space.static_body, (float(x0), float(y0)), (float(x1), float(y1)), _WALL_RADIUS
        )
        seg.friction = math.sqrt(_WALL_FRICTION)
        seg.collision_type = _WALL
        space.add(seg)

    half = 0.5 * grip.push_opening

    def make_fingers(hand: pymunk.Body) -> list[pymunk.Shape]:
        fingers: list[pymunk.Shape] = []
        for side in (-1.0, 1.0):
            f = pymunk.Circle(hand, grip.finger_radius, (0.0, side * half))
            f.friction = math.sqrt(grip.contact_friction)
            f.collision_type = _HAND
            fingers.append(f)
        return fingers

    pusher = TrackedPusher(
        space,
        start,
        grip.mass,
        pymunk.moment_for_box(grip.mass, (2 * grip.finger_radius, grip.push_opening)),
        make_fingers,
        grip.max_force,
        grip.max_torque,
        grip.max_speed,
        hand=world.hand,
    )
    return space, contacts, bodies, parts, pusher


def simulate_push(world: TabletopSpec, scene: SceneInstance, hand_path: np.ndarray) -> PushOutcome:
    """Run one push in a fresh pymunk space.

    Args:
        world: The tabletop world.
        scene: Objects, walls and the push.
        hand_path: (T_c, 3) commanded world ``(x, y, yaw)`` of the hand at each control tick,
            from the arm's joint trajectory (`Arm.trace`). After the last tick the hand holds
            its pose for ``world.settle_time``.

    Returns:
        The push's outcome.

    Raises:
        InputError: If `world` or `scene` is of the wrong type, `scene` holds an invalid
            physical parameter or overlapping objects (see `SceneInstance.validate`) or an
            object whose centre is off the table, or `hand_path` is not a finite (T_c, 3)
            array with T_c >= 1.
    """
    hand_path = _check_push(world, scene, hand_path)
    phys = world.physics
    space, contacts, bodies, parts, pusher = _build(world, scene, hand_path[0])
    hand = pusher.body

    rate = phys.control_rate
    dt = 1.0 / rate / phys.substeps
    n_settle = round(world.settle_time * rate)
    path = np.concatenate([hand_path, np.repeat(hand_path[-1:], n_settle + 1, axis=0)])
    every = max(1, round(rate / world.record_rate))
    hx, hy = 0.5 * world.table_size[0], 0.5 * world.table_size[1]

    K = len(bodies)
    before = np.array([body_pose(b) for b in bodies])
    frozen: list[tuple[float, float, float] | None] = [None] * K
    t_rec, hand_rec, obj_rec, cmd_rec = [], [], [], []
    ticks_hand, ticks_cmd = [body_pose(hand)], [body_pose(pusher.control)]
    lag = 0.0

    def record(t: float) -> None:
        t_rec.append(t)
        hand_rec.append(body_pose(hand))
        cmd_rec.append(body_pose(pusher.control))
        obj_rec.append([frozen[k] or body_pose(b) for k, b in enumerate(bodies)])

    record(0.0)
    for i in range(len(path) - 1):
        pusher.command(path[i], path[i + 1], rate)
        for _ in range(phys.substeps):
            space.step(dt)
        lag = max(lag, pusher.lag(path[i + 1]))
        ticks_hand.append(body_pose(hand))
        ticks_cmd.append(body_pose(pusher.control))
        for k, b in enumerate(bodies):
            if frozen[k] is None and (abs(b.position.x) > hx or abs(b.position.y) > hy):
                frozen[k] = body_pose(b)  # its centre passed the edge: it tips over and falls
                space.remove(*parts[k])
        if (i + 1) % every == 0:
            record((i + 1) / rate)
    if (len(path) - 1) % every:
        record((len(path) - 1) / rate)

    after = np.array([frozen[k] or body_pose(b) for k, b in enumerate(bodies)])
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
        traj_commanded=np.array(cmd_rec),
        reaction=_reaction_samples(
            np.array(ticks_cmd), np.array(ticks_hand), scene.push_yaw, world.hand.reaction_samples
        ),
    )


def _reaction_samples(
    commanded: np.ndarray, actual: np.ndarray, push_yaw: float, samples: int
) -> np.ndarray:
    """The hand's deviation from its command at `samples` evenly spaced ticks.

    Args:
        commanded: (T, 3) commanded world ``(x, y, yaw)`` of the hand at every control tick.
        actual: (T, 3) its actual pose at the same ticks.
        push_yaw: World yaw of z_p (rad).
        samples: R, the points to keep.

    Returns:
        (R, 3) actual minus commanded ``(Delta y_p, Delta z_p, Delta theta)`` in the pushing
        frame, linearly interpolated between ticks.
    """
    deviation = push_frame_effect(commanded, actual, push_yaw)  # (T, 3)
    ticks = np.arange(len(deviation), dtype=float)
    at = np.linspace(0.0, ticks[-1], samples)
    return np.stack([np.interp(at, ticks, deviation[:, c]) for c in range(3)], axis=1)


def _max_penetration(space: pymunk.Space) -> float:
    """Deepest overlap (m) of an object with anything: the hand, a wall or another object."""
    objects = [s for s in space.shapes if s.collision_type >= _OBJECT0]
    return max((contact_depth(space, s) for s in objects), default=0.0)


register_world(
    WorldKind(
        name="tabletop",
        label="tabletop",
        load_world=load_tabletop,
        simulate=simulate_push,
        scenes=SCENES,
        load_scene=load_scene,
        dataset_kind="push",
        actions="push",
        order=0,
    )
)
