"""The side-view pick-and-place world in pymunk 7.

The simulated plane is the world x-z plane: pymunk's (x, y) are world (x, z), gravity pulls
along -z and a pose is ``(x, z, phi)``, phi counter-clockwise as seen from -y (a rotation about
the viewing axis). The table is a static segment whose top is the plane z = 0. Objects are
dynamic boxes resting on the table or stacked on one another. pymunk multiplies the two shapes'
friction coefficients at a contact, so each shape is given the square root of its coefficient
and a contact pair sees the geometric mean.

The hand is a dynamic palm, without collision shapes, that tracks the arm's FK through a
force- and torque-limited constraint (`probaff.sim.pusher.TrackedPusher`), and two dynamic
finger bodies. Each finger slides in a groove of the palm along the closing axis (world x at
phi = 0), keeps the palm's angle, and is driven towards its commanded opening by a pin joint
whose force is limited to the squeeze force: a closed finger presses on an object with at most
that force. A centring spring couples the two fingers symmetrically about the tcp, as the
mimic joint of a parallel gripper does, without adding to the squeeze. A grasp holds by
friction alone; nothing welds the object to the hand.

The module registers the ``sideview`` world kind (`probaff.sim.registry`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pymunk

from probaff._checks import check_count, check_finite, check_positive, check_shape
from probaff.errors import ConfigError, InputError
from probaff.sim.geometry import body_pose, convex_penetration
from probaff.sim.inputs import check_objects, check_type, floats, numeric_fields
from probaff.sim.pusher import TrackedPusher
from probaff.sim.registry import WorldKind, register_world
from probaff.sim.sideview_config import (
    SCENES,
    SKILLS,
    SideViewSpec,
    load_sideview,
    load_sideview_scene,
)
from probaff.sim.specs import ObjectSpec, load_catalogue

__all__ = ["SideViewRun", "SideViewScene", "simulate_rest", "simulate_sideview"]

_TABLE, _FINGER, _OBJECT0 = 1, 2, 10
_TABLE_RADIUS = 0.01
_OVERLAP_TOL = 1e-3  # penetration (m) between start boxes that counts as an overlap
_FALLEN_Z = -0.5  # an object whose centre drops below this left the table (m)
_HAND_GROUP = 1
# The fingers are coupled, as a parallel gripper's are: a spring pulls each towards the mean
# offset of the two, which centres the pair without changing their squeeze.
_CENTRING_STIFFNESS = 400.0  # N/m
_CENTRING_DAMPING = 10.0  # N s/m


def _corners(obj: ObjectSpec, pose: np.ndarray) -> np.ndarray:
    """(4, 2) world (x, z) corners of a box at pose (x, z, phi)."""
    w, h = 0.5 * obj.size[0], 0.5 * obj.height
    c, s = math.cos(pose[2]), math.sin(pose[2])
    local = np.array([[-w, -h], [w, -h], [w, h], [-w, h]])
    return local @ np.array([[c, s], [-s, c]]) + pose[:2]


@dataclass(frozen=True)
class SideViewScene:
    """One fully specified side-view scene, ready for a skill.

    Attributes:
        skill: ``"pick"`` or ``"place"``.
        objects: Catalogue specs of the K boxes.
        poses: (K, 3) world ``(x, z, phi)`` of the box centres at the start; for place, the
            held object's pose is where the hand holds it.
        mass: (K,) masses (kg).
        friction: (K,) surface friction coefficients.
        target: Pick: index of the object to pick; place: index of the held object.
        support: Place: index of the object the held one goes onto, -1 for the table.
        release_height: Place: height of the held object's bottom above the target top when
            the fingers open (m).
    """

    skill: str
    objects: tuple[ObjectSpec, ...]
    poses: np.ndarray
    mass: np.ndarray
    friction: np.ndarray
    target: int
    support: int = -1
    release_height: float = 0.0

    def __post_init__(self) -> None:
        objects = check_objects(
            "SideViewScene", self.objects, "load_catalogue(load_sideview().catalogue)"
        )
        object.__setattr__(self, "objects", objects)
        numeric_fields(self, ("poses", "mass", "friction"))
        object.__setattr__(
            self, "target", check_count("SideViewScene.target", self.target, minimum=0)
        )
        object.__setattr__(
            self, "support", check_count("SideViewScene.support", self.support, minimum=-1)
        )
        try:
            release = float(self.release_height)
        except (TypeError, ValueError):
            raise InputError(
                f"SideViewScene.release_height must be a number, got {self.release_height!r}."
            ) from None
        object.__setattr__(self, "release_height", release)
        self.validate()

    def validate(self) -> None:
        """Check every field, so that nothing invalid reaches pymunk.

        Runs on construction and again before a simulation (the arrays are mutable).

        Raises:
            InputError: Naming the field, for an unknown skill, a wrong shape, a NaN or
                infinite value, a mass <= 0, a negative friction, a bad index, a release
                height out of range, or objects that overlap each other or the table.
        """
        if self.skill not in SKILLS:
            raise InputError(
                f"SideViewScene.skill must be one of {list(SKILLS)}, got {self.skill!r}."
            )
        K = len(self.objects)
        for obj in self.objects:
            if obj.shape != "box":
                raise InputError(
                    f"SideViewScene.objects: {obj.name!r} is a {obj.shape}; the side view "
                    "holds boxes only."
                )
        for name, shape in (("poses", (K, 3)), ("mass", (K,)), ("friction", (K,))):
            check_shape(f"SideViewScene.{name}", getattr(self, name), shape)
            check_finite(f"SideViewScene.{name}", getattr(self, name))
        for k in range(K):
            check_positive(f"SideViewScene.mass[{k}]", float(self.mass[k]))
            check_positive(f"SideViewScene.friction[{k}]", float(self.friction[k]), allow_zero=True)
        target = check_count("SideViewScene.target", self.target, minimum=0)
        if target >= K:
            raise InputError(f"SideViewScene.target {target} is not an object index (0..{K - 1}).")
        check_finite("SideViewScene.release_height", self.release_height)
        if self.skill == "place":
            support = check_count("SideViewScene.support", self.support, minimum=-1)
            if support >= K or support == target:
                raise InputError(
                    f"SideViewScene.support {support} must be -1 (the table) or the index of an "
                    f"object other than the held one (target {target}), of {K} objects."
                )
            check_positive("SideViewScene.release_height", self.release_height, allow_zero=True)
            gap = self.poses[target, 1] - 0.5 * self.objects[target].height - self.support_top
            if gap < self.release_height:
                raise InputError(
                    f"SideViewScene.release_height {self.release_height} must not exceed the "
                    f"held object's start height {gap:.4f} m above its target; the object is "
                    "lowered, never raised."
                )
        corners = [_corners(o, p) for o, p in zip(self.objects, self.poses, strict=True)]
        for k, c in enumerate(corners):
            if c[:, 1].min() < -_OVERLAP_TOL:
                raise InputError(
                    f"SideViewScene.poses[{k}] puts {self.objects[k].name!r} into the table "
                    f"(its lowest corner at z={c[:, 1].min():.4f} m); raise it to z >= h/2."
                )
        for i in range(K):
            for j in range(i + 1, K):
                if convex_penetration(corners[i], corners[j]) > _OVERLAP_TOL:
                    raise InputError(
                        f"SideViewScene.poses: objects {i} ({self.objects[i].name}) and {j} "
                        f"({self.objects[j].name}) overlap at the start; move them apart or "
                        "stack one on the other."
                    )

    @property
    def support_top(self) -> float:
        """World z of the place target's surface: the table (0) or the support's top (m)."""
        if self.support < 0:
            return 0.0
        return float(self.poses[self.support, 1] + 0.5 * self.objects[self.support].height)

    @classmethod
    def nominal(
        cls,
        skill: str,
        objects: Sequence[ObjectSpec | str],
        poses: np.ndarray,
        target: int,
        support: int = -1,
        release_height: float = 0.0,
        catalogue: dict[str, ObjectSpec] | None = None,
    ) -> SideViewScene:
        """A scene with the catalogue's masses and frictions.

        Args:
            skill: ``"pick"`` or ``"place"``.
            objects: K catalogue objects, or their names in the side-view catalogue.
            poses: (K, 3) world ``(x, z, phi)``.
            target: See `SideViewScene`.
            support: See `SideViewScene`.
            release_height: See `SideViewScene`.
            catalogue: The catalogue that names resolve in; by default the side-view one.

        Raises:
            ConfigError: For an unknown object name.
            InputError: For any invalid field (see `validate`).
        """
        if isinstance(objects, (str, ObjectSpec)) or not isinstance(objects, Sequence):
            raise InputError(
                f"objects must be a list of catalogue names or ObjectSpec, got {objects!r}."
            )
        specs: list[ObjectSpec] = []
        for o in objects:
            if isinstance(o, str):
                cat = (
                    catalogue
                    if catalogue is not None
                    else load_catalogue(load_sideview().catalogue)
                )
                if o not in cat:
                    raise ConfigError(
                        f"objects: unknown object {o!r}; the side-view catalogue has {sorted(cat)}."
                    )
                specs.append(cat[o])
            else:
                specs.append(o)
        return cls(
            skill=skill,
            objects=tuple(specs),
            poses=np.asarray(poses, dtype=float),
            mass=np.array([o.mass for o in specs if isinstance(o, ObjectSpec)]),
            friction=np.array([o.contact_friction for o in specs if isinstance(o, ObjectSpec)]),
            target=target,
            support=support,
            release_height=release_height,
        )


@dataclass(frozen=True)
class SideViewRun:
    """Recorded trajectories of one side-view simulation (after the settle).

    Attributes:
        times: (T,) sample times (s), 0 when the hand starts along its path.
        hand_commanded: (T, 3) commanded world ``(x, z, phi)`` of the tcp.
        hand: (T, 3) actual world ``(x, z, phi)`` of the tcp.
        opening_commanded: (T,) commanded gap between the finger pads (m).
        opening: (T,) actual gap between the finger pads (m).
        objects: (T, K, 3) world ``(x, z, phi)`` of the objects.
        state_before: (K, 3) object poses after the settle, when the path starts.
        state_after: (K, 3) object poses at the end.
        snap_hand: (S, 3) actual tcp pose at each requested snapshot tick.
        snap_objects: (S, K, 3) object poses at the snapshots.
        snap_opening: (S,) actual gap between the finger pads at the snapshots (m).
        snap_fingers: (S, K) number of fingers (0-2) touching each object at the snapshots.
        snap_supported: (S, K) each object touches the table or another object.
    """

    times: np.ndarray
    hand_commanded: np.ndarray
    hand: np.ndarray
    opening_commanded: np.ndarray
    opening: np.ndarray
    objects: np.ndarray
    state_before: np.ndarray
    state_after: np.ndarray
    snap_hand: np.ndarray
    snap_objects: np.ndarray
    snap_opening: np.ndarray
    snap_fingers: np.ndarray
    snap_supported: np.ndarray


class _Gripper:
    """The palm and its two fingers in a space."""

    def __init__(
        self, space: pymunk.Space, world: SideViewSpec, pose: np.ndarray, opening: float
    ) -> None:
        g = world.gripper
        self.t, length = g.finger_size
        self.centre_up = 0.5 * length - g.tip_below_tcp  # finger centre above the tcp (m)
        self.palm = TrackedPusher(
            space,
            pose,
            g.hand_mass,
            pymunk.moment_for_box(g.hand_mass, (g.span + 2 * self.t, 0.05)),
            lambda body: [],
            g.max_force,
            g.max_torque,
            g.max_speed,
            hand=world.hand,
            compensated_mass=2 * g.finger_mass,
        )
        hand = self.palm.body
        self.fingers: list[pymunk.Body] = []
        self.pins: list[pymunk.PinJoint] = []
        self.springs: list[pymunk.DampedSpring] = []
        self._commanded = self._offset(opening)
        self.shapes: list[pymunk.Shape] = []
        for side in (-1.0, 1.0):
            finger = pymunk.Body(
                g.finger_mass, pymunk.moment_for_box(g.finger_mass, (self.t, length))
            )
            finger.position = hand.local_to_world((side * self._offset(opening), self.centre_up))
            finger.angle = hand.angle
            shape = pymunk.Poly.create_box(finger, (self.t, length))
            shape.friction = math.sqrt(g.pad_friction)
            shape.elasticity = 0.0
            shape.collision_type = _FINGER
            shape.filter = pymunk.ShapeFilter(group=_HAND_GROUP)
            groove = pymunk.GrooveJoint(
                hand,
                finger,
                (side * 0.5 * self.t, self.centre_up),
                (side * self._offset(g.span), self.centre_up),
                (0.0, 0.0),
            )
            gear = pymunk.GearJoint(hand, finger, 0.0, 1.0)
            pin = pymunk.PinJoint(hand, finger, (0.0, self.centre_up), (0.0, 0.0))
            pin.distance = self._offset(opening)
            pin.max_force, pin.max_bias = g.squeeze_force, g.finger_speed
            spring = pymunk.DampedSpring(
                hand,
                finger,
                (0.0, self.centre_up),
                (0.0, 0.0),
                self._offset(opening),
                _CENTRING_STIFFNESS,
                _CENTRING_DAMPING,
            )
            space.add(finger, shape, groove, gear, pin, spring)
            self.fingers.append(finger)
            self.pins.append(pin)
            self.springs.append(spring)
            self.shapes.append(shape)

    def _offset(self, opening: float) -> float:
        """Distance of a finger's centre from the closing axis' centre for a pad gap (m)."""
        return 0.5 * opening + 0.5 * self.t

    def command(self, now: np.ndarray, nxt: np.ndarray, rate: float, opening: float) -> None:
        """Command the tcp from pose `now` to `nxt` over one tick, and the pad gap."""
        self.palm.command(now, nxt, rate)
        d = self._offset(opening)
        if d != self._commanded:
            self._commanded = d
            for pin in self.pins:
                pin.distance = d
        hand = self.palm.body
        left, right = (hand.world_to_local(f.position).x for f in self.fingers)
        mean = 0.5 * (right - left)  # the springs pull both fingers to the mean offset
        for spring in self.springs:
            spring.rest_length = mean

    def tcp(self) -> tuple[float, float, float]:
        """Actual world (x, z, phi) of the tcp."""
        return body_pose(self.palm.body)

    def opening(self) -> float:
        """Actual gap between the finger pads (m)."""
        hand = self.palm.body
        left, right = (hand.world_to_local(f.position).x for f in self.fingers)
        return float(right - left - self.t)


def _contacts(body: pymunk.Body, fingers: list[pymunk.Shape]) -> tuple[int, bool]:
    """(number of fingers touching `body`, whether it touches the table or another object)."""
    touching: set[int] = set()
    other = [False]

    def visit(arbiter: pymunk.Arbiter) -> None:
        for shape in arbiter.shapes:
            if shape.body is body:
                continue
            if shape.collision_type == _FINGER:
                touching.add(fingers.index(shape))
            else:
                other[0] = True

    body.each_arbiter(visit)
    return len(touching), other[0]


def _build(world: SideViewSpec, scene: SideViewScene) -> tuple[pymunk.Space, list[pymunk.Body]]:
    phys = world.physics
    space = pymunk.Space()
    space.gravity = (0.0, -phys.gravity)
    space.iterations = phys.iterations
    space.collision_slop = phys.collision_slop
    half = 0.5 * world.table_length
    table = pymunk.Segment(
        space.static_body, (-half, -_TABLE_RADIUS), (half, -_TABLE_RADIUS), _TABLE_RADIUS
    )
    table.friction = math.sqrt(world.table_friction)
    table.collision_type = _TABLE
    space.add(table)
    bodies = []
    for k, obj in enumerate(scene.objects):
        m, size = float(scene.mass[k]), (obj.size[0], obj.height)
        body = pymunk.Body(m, pymunk.moment_for_box(m, size))
        body.position = (float(scene.poses[k, 0]), float(scene.poses[k, 1]))
        body.angle = float(scene.poses[k, 2])
        shape = pymunk.Poly.create_box(body, size)
        shape.friction = math.sqrt(float(scene.friction[k]))
        shape.elasticity = 0.0
        shape.collision_type = _OBJECT0 + k
        space.add(body, shape)
        bodies.append(body)
    return space, bodies


def _check_on_table(world: SideViewSpec, scene: SideViewScene) -> None:
    check_type("world", world, SideViewSpec, "load_sideview()")
    check_type("scene", scene, SideViewScene, "SideViewScene.nominal or sample_sideview_scenes")
    scene.validate()
    half = 0.5 * world.table_length
    for k, p in enumerate(scene.poses):
        if abs(p[0]) > half:
            raise InputError(
                f"SideViewScene.poses[{k}] has its centre at x={p[0]:.3f} m, off the table "
                f"(|x| <= {half}); move it onto the table."
            )


def simulate_rest(
    world: SideViewSpec, scene: SideViewScene, duration: float
) -> tuple[np.ndarray, np.ndarray]:
    """Let the objects of a scene rest under gravity, without the hand.

    Args:
        world: The side-view world.
        scene: The objects (its skill fields are not used).
        duration: Simulated time (s), > 0.

    Returns:
        ``(times, objects)``: times (T,) s and world ``(x, z, phi)`` of the objects (T, K, 3),
        sampled at the world's record rate.

    Raises:
        InputError: For a world or scene of the wrong type, an invalid scene, an object off
            the table, or a duration that is not a finite number > 0.
    """
    _check_on_table(world, scene)
    if isinstance(duration, (bool, str, bytes)):
        raise InputError(f"duration must be a finite number > 0 (s), got {duration!r}.")
    check_positive("duration", duration)
    duration = float(duration)
    space, bodies = _build(world, scene)
    phys = world.physics
    dt = 1.0 / phys.control_rate / phys.substeps
    every = max(1, round(phys.control_rate / phys.record_rate))
    n = max(1, round(duration * phys.control_rate))
    times, objs = [0.0], [[body_pose(b) for b in bodies]]
    for i in range(n):
        for _ in range(phys.substeps):
            space.step(dt)
        if (i + 1) % every == 0 or i == n - 1:
            times.append((i + 1) / phys.control_rate)
            objs.append([body_pose(b) for b in bodies])
    return np.array(times), np.array(objs)


def _check_paths(
    world: SideViewSpec,
    hand_path: object,
    opening_path: object,
    initial_opening: object,
    snapshots: Sequence[int],
) -> tuple[np.ndarray, np.ndarray, float, list[int]]:
    """The checked ``(hand_path, opening_path, initial opening, snapshot ticks)``.

    Raises:
        InputError: As `simulate_sideview` documents.
    """
    hand = floats("hand_path", hand_path)
    check_shape("hand_path", hand, (None, 3))
    if len(hand) == 0:
        raise InputError("hand_path is empty; give at least one (x, z, phi) control tick.")
    check_finite("hand_path", hand)
    T = len(hand)
    opening = floats("opening_path", opening_path)
    check_shape("opening_path", opening, (T,))
    check_finite("opening_path", opening)
    span = world.gripper.span
    if initial_opening is None:
        start = float(opening[0])
    else:
        start_arr = floats("initial_opening", initial_opening)
        check_shape("initial_opening", start_arr, ())
        check_finite("initial_opening", start_arr)
        start = float(start_arr)
    if opening.min() < 0 or opening.max() > span + 1e-9 or not 0 <= start <= span + 1e-9:
        raise InputError(
            f"opening_path and initial_opening must lie in [0, {span}] m (the gripper's span)."
        )
    snaps = [check_count("snapshots[i]", s, minimum=0) for s in snapshots]
    if any(s >= T for s in snaps):
        raise InputError(f"snapshots must be control ticks in 0..{T - 1}, got {list(snapshots)}.")
    return hand, opening, start, snaps


def simulate_sideview(
    world: SideViewSpec,
    scene: SideViewScene,
    hand_path: np.ndarray,
    opening_path: np.ndarray,
    initial_opening: float | None = None,
    snapshots: Sequence[int] = (),
) -> SideViewRun:
    """Settle a scene, then drive the hand along a path in a fresh pymunk space.

    Args:
        world: The side-view world.
        scene: Objects (and the skill's fields, for validation).
        hand_path: (T_c, 3) commanded world ``(x, z, phi)`` of the tcp at each control tick,
            from the arm's joint trajectory (`Arm.sideview_trace`). During the settle the hand
            holds ``hand_path[0]``.
        opening_path: (T_c,) commanded gap between the finger pads (m), in [0, span].
        initial_opening: The fingers' actual gap at the start (m); ``opening_path[0]`` by
            default. A held object starts between fingers placed at its faces.
        snapshots: Control ticks (0..T_c - 1) at which contacts and poses are recorded.

    Returns:
        The recorded trajectories.

    Raises:
        InputError: For a world or scene of the wrong type, an invalid scene, an object off
            the table, a path that is not finite or of the wrong shape, an opening outside
            [0, span], or a snapshot out of range.
    """
    _check_on_table(world, scene)
    hand_path, opening_path, start, snaps = _check_paths(
        world, hand_path, opening_path, initial_opening, snapshots
    )
    T = len(hand_path)
    phys = world.physics
    space, bodies = _build(world, scene)
    grip = _Gripper(space, world, hand_path[0], start)
    rate = phys.control_rate
    dt = 1.0 / rate / phys.substeps
    K = len(bodies)
    objects = _Objects(space, bodies)
    poses = objects.poses

    def step_tick() -> None:
        for _ in range(phys.substeps):
            space.step(dt)
        objects.drop_fallen()

    for _ in range(round(phys.settle_time * rate)):
        grip.command(hand_path[0], hand_path[0], rate, float(opening_path[0]))
        step_tick()

    every = max(1, round(rate / phys.record_rate))
    before = np.array(poses())
    t_rec, cmd_rec, hand_rec, oc_rec, o_rec, obj_rec = [], [], [], [], [], []
    snap_set = set(snaps)
    snap_at: dict[int, tuple] = {}

    def record(i: int) -> None:
        t_rec.append(i / rate)
        cmd_rec.append(hand_path[i])
        hand_rec.append(grip.tcp())
        oc_rec.append(opening_path[i])
        o_rec.append(grip.opening())
        obj_rec.append(poses())

    def snapshot(i: int) -> None:
        touch = [_contacts(b, grip.shapes) for b in bodies]
        snap_at[i] = (
            grip.tcp(),
            poses(),
            grip.opening(),
            [c[0] for c in touch],
            [c[1] for c in touch],
        )

    record(0)
    if 0 in snap_set:
        snapshot(0)
    for i in range(T - 1):
        grip.command(hand_path[i], hand_path[i + 1], rate, float(opening_path[i + 1]))
        step_tick()
        if (i + 1) % every == 0 or i + 1 == T - 1:
            record(i + 1)
        if i + 1 in snap_set:
            snapshot(i + 1)
    return SideViewRun(
        times=np.array(t_rec),
        hand_commanded=np.array(cmd_rec),
        hand=np.array(hand_rec),
        opening_commanded=np.array(oc_rec),
        opening=np.array(o_rec),
        objects=np.array(obj_rec).reshape(-1, K, 3),
        state_before=before,
        state_after=np.array(poses()),
        **_snapshot_arrays([snap_at[s] for s in snaps], K),
    )


class _Objects:
    """The scene's bodies in a space; one whose centre drops below the table leaves it."""

    def __init__(self, space: pymunk.Space, bodies: list[pymunk.Body]) -> None:
        self.space, self.bodies = space, bodies
        self.fallen: list[tuple[float, float, float] | None] = [None] * len(bodies)

    def drop_fallen(self) -> None:
        """Freeze the pose of each body that fell off the table and remove it from the space."""
        for k, b in enumerate(self.bodies):
            if self.fallen[k] is None and b.position.y < _FALLEN_Z:
                self.fallen[k] = body_pose(b)
                self.space.remove(b, *b.shapes)

    def poses(self) -> list[tuple[float, float, float]]:
        """World ``(x, z, phi)`` of every object, a fallen one where it fell."""
        return [self.fallen[k] or body_pose(b) for k, b in enumerate(self.bodies)]


def _snapshot_arrays(snaps: list[tuple], k: int) -> dict[str, np.ndarray]:
    """The ``snap_*`` arrays of `SideViewRun` of `k` objects.

    Args:
        snaps: Per snapshot, ``(tcp, poses, opening, fingers, supported)``.
        k: Number of objects.
    """
    return {
        "snap_hand": np.array([s[0] for s in snaps]).reshape(-1, 3),
        "snap_objects": np.array([s[1] for s in snaps]).reshape(-1, k, 3),
        "snap_opening": np.array([s[2] for s in snaps], dtype=float),
        "snap_fingers": np.array([s[3] for s in snaps], dtype=int).reshape(-1, k),
        "snap_supported": np.array([s[4] for s in snaps], dtype=bool).reshape(-1, k),
    }


def _describe_scene(name: str) -> str:
    spec = load_sideview_scene(name)
    return f"side view, {spec.skill}: {spec.description}"


register_world(
    WorldKind(
        name="sideview",
        label="side-view",
        load_world=load_sideview,
        simulate=simulate_sideview,
        scenes=SCENES,
        load_scene=load_sideview_scene,
        dataset_kind="skill",
        actions="pick/place",
        describe_scene=_describe_scene,
        order=1,
    )
)
