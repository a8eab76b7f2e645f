"""Office scenes of chapter 2 with ground-truth affordance labels, one label vector per object.

A scene is a room (a floor and some walls) holding tables (a top on four legs or on one central
cylinder), chairs (seat, back and four legs, square or round) and boxes of several sizes on the
floor, on table tops and stacked on floor boxes. Its solids form a `PrimitiveScene` for the depth
camera; each object has an integer id, a kind, its parts and the id of what it stands on.

Frames and units: world frame, z up from the floor (the floor's top is z = 0), metres, kilograms;
yaws in radians in code and in degrees in ``worlds/office.yaml``. The floor spans the rectangle
``room.x`` by ``room.y``; walls stand just outside it. Every sampled object's yaw is a multiple
of 90 degrees, so its footprint is axis-aligned in the world (the label rules take any yaw). The
robot stands at ``robot.pose`` ``(x, y, yaw)`` and looks along its own +x: the push directions
are in the robot frame, forward = robot +x, backward = -x, left = +y, right = -y. With the
default pose (origin, yaw 0) the robot frame is the world frame.

The ground-truth labels follow the thesis's manual labelling criteria
(`probaff.sim.office_labels`); the world file is read by `probaff.sim.office_config` and the
objects are checked for a consistent scene by `probaff.sim.office_objects`.

Sampling (rejection sampling with ``placement.max_tries`` tries per object): floor objects keep
``placement.min_clearance`` (0.02 m, our choice: no two solids touch, so every point has one
object id) from each other and from the floor's edges, and stay ``robot.keep_out`` (0.6 m, our
choice: the PR2 base's half diagonal, 0.47 m, and a margin) from the robot. A floor object is
put against a wall with probability ``placement.against_wall_probability`` and next to an
earlier floor object with probability ``placement.next_to_probability``, at a gap drawn from
``placement.near_gap`` (0.02-0.10 m, below the push clearance, so that such neighbours block);
otherwise anywhere on the floor. A chair next to a table faces it; a chair against a wall turns
its back to it. Boxes on a table or a box lie wholly on its top, ``min_clearance`` apart from
each other and from its edges; a box meant for a table or a stack that fits on no table or
free floor box within the tries (the tops are full) goes to the floor instead.

The module registers the ``office`` world kind (`probaff.sim.registry`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from probaff._checks import check_count, check_finite, check_shape
from probaff.affordance_labels import LABELS
from probaff.errors import ConfigError, InputError
from probaff.sim.inputs import floats
from probaff.sim.office_config import (
    OfficeBoxClass,
    OfficeBoxesSpec,
    OfficeChairSpec,
    OfficeLabelRules,
    OfficeSpec,
    OfficeTableSpec,
    load_office,
)
from probaff.sim.office_labels import office_labels
from probaff.sim.office_objects import OfficeObject
from probaff.sim.primitives import PrimitiveScene
from probaff.sim.registry import WorldKind, register_world
from probaff.sim.world_files import Range

__all__ = [
    "OfficeScene",
    "assemble_office_scene",
    "sample_office_scene",
    "sample_office_scenes",
]


@dataclass(frozen=True, eq=False)
class OfficeScene:
    """An office scene with its ground truth.

    Attributes:
        primitives: The solids, each tagged with its object's id (for the camera).
        objects: The K objects, floor and walls included.
        labels: (K, 6) bool, row k for ``objects[k]``, columns in the order of `LABELS`.
        robot_pose: ``(x, y, yaw)`` of the robot (m, m, rad, world frame); the labels' push
            directions are in its frame.
    """

    primitives: PrimitiveScene
    objects: tuple[OfficeObject, ...]
    labels: np.ndarray
    robot_pose: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        labels = np.asarray(self.labels)
        check_shape("labels", labels, (len(self.objects), len(LABELS)))
        if labels.dtype != bool:
            raise InputError(f"labels must be bool, got {labels.dtype}.")
        object.__setattr__(self, "labels", labels)

    def label_of(self, object_id: int) -> np.ndarray:
        """(6,) bool labels of the object with id `object_id`, in the order of `LABELS`.

        Raises:
            InputError: If no object has that id.
        """
        oid = check_count("object_id", object_id, minimum=0)
        for k, o in enumerate(self.objects):
            if o.id == oid:
                return self.labels[k].copy()
        raise InputError(
            f"object_id {oid} is not in the scene; its ids are {[o.id for o in self.objects]}."
        )


def assemble_office_scene(
    objects: Sequence[OfficeObject],
    rules: OfficeLabelRules,
    robot_pose: tuple[float, float, float] = (0.0, 0.0, 0.0),
) -> OfficeScene:
    """Build the primitives and ground-truth labels of a scene from its objects.

    Args:
        objects: The K objects (ids unique, supports among them or -1).
        rules: The label thresholds.
        robot_pose: ``(x, y, yaw)`` of the robot (m, m, rad, world frame).

    Raises:
        InputError: For objects that are not `OfficeObject`, duplicate ids, an unknown
            support, a support on the floor or a wall, supports that form a cycle, two objects
            whose solids interpenetrate (more than 1 um), an object on the floor that does not
            stand at z = 0 or reaches off the floor object, an object that does not rest on a
            top face of its support, or a non-finite pose; each message names the objects.
    """
    pose_arr = floats("robot_pose", robot_pose)
    check_shape("robot_pose", pose_arr, (3,))
    check_finite("robot_pose", pose_arr)
    objs = tuple(objects)
    labels = office_labels(objs, rules, float(pose_arr[2]))
    prims = PrimitiveScene(
        boxes=np.concatenate([o.boxes for o in objs]),
        box_ids=np.concatenate([np.full(len(o.boxes), o.id, dtype=np.int64) for o in objs]),
        cylinders=np.concatenate([o.cylinders for o in objs]),
        cylinder_ids=np.concatenate(
            [np.full(len(o.cylinders), o.id, dtype=np.int64) for o in objs]
        ),
    )
    pose = (float(pose_arr[0]), float(pose_arr[1]), float(pose_arr[2]))
    return OfficeScene(primitives=prims, objects=objs, labels=labels, robot_pose=pose)


_Parts = tuple[np.ndarray, np.ndarray]  # (P, 7) boxes, (Q, 5) cylinders


def _uniform(rng: np.random.Generator, r: Range) -> float:
    return float(rng.uniform(r[0], r[1]))


def _table_parts(spec: OfficeTableSpec, rng: np.random.Generator) -> _Parts:
    """A table at the origin, yaw 0, standing on z = 0: its length along x."""
    L, D = _uniform(rng, spec.top_length), _uniform(rng, spec.top_depth)
    t, H = _uniform(rng, spec.top_thickness), _uniform(rng, spec.height)
    boxes = [[0.0, 0.0, H - t / 2, L, D, t, 0.0]]
    cylinders = []
    if rng.random() < spec.pedestal_probability:
        cylinders.append([0.0, 0.0, (H - t) / 2, _uniform(rng, spec.pedestal_radius), H - t])
    else:
        leg = _uniform(rng, spec.leg_size)
        ox, oy = L / 2 - spec.leg_inset - leg / 2, D / 2 - spec.leg_inset - leg / 2
        for sx, sy in ((1, 1), (1, -1), (-1, 1), (-1, -1)):
            boxes.append([sx * ox, sy * oy, (H - t) / 2, leg, leg, H - t, 0.0])
    return np.array(boxes), np.array(cylinders).reshape(-1, 5)


def _chair_parts(spec: OfficeChairSpec, rng: np.random.Generator) -> _Parts:
    """A chair at the origin facing +x, standing on z = 0: its back along its -x edge."""
    W, Dp = _uniform(rng, spec.seat_width), _uniform(rng, spec.seat_depth)
    hs, ts = _uniform(rng, spec.seat_height), _uniform(rng, spec.seat_thickness)
    hb, tb = _uniform(rng, spec.back_height), _uniform(rng, spec.back_thickness)
    leg = _uniform(rng, spec.leg_size)
    boxes = [
        [0.0, 0.0, hs - ts / 2, Dp, W, ts, 0.0],
        [-Dp / 2 + tb / 2, 0.0, (hs + hb) / 2, tb, W, hb - hs, 0.0],
    ]
    cylinders = []
    round_legs = rng.random() < spec.cylinder_leg_probability
    ox, oy = Dp / 2 - leg / 2, W / 2 - leg / 2
    for sx, sy in ((1, 1), (1, -1), (-1, 1), (-1, -1)):
        if round_legs:
            cylinders.append([sx * ox, sy * oy, (hs - ts) / 2, leg / 2, hs - ts])
        else:
            boxes.append([sx * ox, sy * oy, (hs - ts) / 2, leg, leg, hs - ts, 0.0])
    return np.array(boxes), np.array(cylinders).reshape(-1, 5)


def _box_class(spec: OfficeBoxesSpec, rng: np.random.Generator) -> OfficeBoxClass:
    w = np.array([c.weight for c in spec.classes])
    return spec.classes[int(rng.choice(len(w), p=w / w.sum()))]


def _box_parts(cls: OfficeBoxClass, rng: np.random.Generator) -> _Parts:
    L, W, H = _uniform(rng, cls.length), _uniform(rng, cls.width), _uniform(rng, cls.height)
    return np.array([[0.0, 0.0, H / 2, L, W, H, 0.0]]), np.zeros((0, 5))


def _place(parts: _Parts, x: float, y: float, z: float, quarter_turns: int) -> _Parts:
    """Turn `parts` (built at the origin) by a multiple of 90 degrees, then move them."""
    yaw = quarter_turns * math.pi / 2
    c, s = round(math.cos(yaw)), round(math.sin(yaw))
    boxes, cyl = parts[0].copy(), parts[1].copy()
    for arr in (boxes, cyl):
        u, v = arr[:, 0].copy(), arr[:, 1].copy()
        arr[:, 0], arr[:, 1] = x + c * u - s * v, y + s * u + c * v
        arr[:, 2] += z
    boxes[:, 6] = (boxes[:, 6] + yaw + math.pi) % (2 * math.pi) - math.pi
    return boxes, cyl


def _half_extents(parts: _Parts, quarter_turns: int) -> tuple[float, float]:
    """Half extents (x, y) of the footprint of `parts` (centred on the origin) after turning."""
    b, c = parts
    hx = max(
        np.max(np.abs(b[:, 0]) + b[:, 3] / 2, initial=0.0),
        np.max(np.abs(c[:, 0]) + c[:, 3], initial=0.0),
    )
    hy = max(
        np.max(np.abs(b[:, 1]) + b[:, 4] / 2, initial=0.0),
        np.max(np.abs(c[:, 1]) + c[:, 3], initial=0.0),
    )
    return (float(hy), float(hx)) if quarter_turns % 2 else (float(hx), float(hy))


@dataclass
class _Footprint:
    """An axis-aligned footprint: centre (x, y) and half extents (m, world)."""

    x: float
    y: float
    hx: float
    hy: float

    def apart(self, other: _Footprint, gap: float) -> bool:
        return (
            abs(self.x - other.x) >= self.hx + other.hx + gap - 1e-12
            or abs(self.y - other.y) >= self.hy + other.hy + gap - 1e-12
        )


_SIDES = {"+x": (0, 1), "-x": (0, -1), "+y": (1, 1), "-y": (1, -1)}
# Quarter turns that make a chair (facing its +x) face away from `side`: a chair with a wall on
# its +x side, or standing on the +x side of a table, faces -x (its back to the wall, its front
# to the table).
_FACE_AWAY = {"+x": 2, "-x": 0, "+y": 3, "-y": 1}


class _Sampler:
    """Rejection sampling of one scene (see the module docstring)."""

    def __init__(self, spec: OfficeSpec, rng: np.random.Generator) -> None:
        self.spec, self.rng = spec, rng
        self.objects: list[OfficeObject] = []
        self.floor_prints: list[tuple[int, str, _Footprint]] = []
        self.on_top: dict[int, list[_Footprint]] = {}

    def _new_id(self) -> int:
        return len(self.objects)

    def room(self) -> None:
        r = self.spec.room
        (x0, x1), (y0, y1) = r.x, r.y
        t, h, f = r.wall_thickness, r.wall_height, r.floor_thickness
        cx, cy, lx, ly = (x0 + x1) / 2, (y0 + y1) / 2, x1 - x0, y1 - y0
        floor = [[cx, cy, -f / 2, lx, ly, f, 0.0]]
        self.objects.append(OfficeObject(0, "floor", "floor", -1, np.array(floor)))
        geometry = {
            "+x": [x1 + t / 2, cy, h / 2, t, ly, h, 0.0],
            "-x": [x0 - t / 2, cy, h / 2, t, ly, h, 0.0],
            "+y": [cx, y1 + t / 2, h / 2, lx + 2 * t, t, h, 0.0],
            "-y": [cx, y0 - t / 2, h / 2, lx + 2 * t, t, h, 0.0],
        }
        for side in r.walls:
            self.objects.append(
                OfficeObject(self._new_id(), "wall", f"wall_{side}", -1, np.array([geometry[side]]))
            )

    def _fits_floor(self, fp: _Footprint) -> bool:
        r, c = self.spec.room, self.spec.placement.min_clearance
        inside = (
            fp.x - fp.hx >= r.x[0] + c - 1e-12
            and fp.x + fp.hx <= r.x[1] - c + 1e-12
            and fp.y - fp.hy >= r.y[0] + c - 1e-12
            and fp.y + fp.hy <= r.y[1] - c + 1e-12
        )
        if not inside:
            return False
        rb = self.spec.robot
        dx = max(abs(rb.x - fp.x) - fp.hx, 0.0)
        dy = max(abs(rb.y - fp.y) - fp.hy, 0.0)
        if math.hypot(dx, dy) < rb.keep_out:
            return False
        return all(fp.apart(o, c) for _, _, o in self.floor_prints)

    def _floor_pose(self, kind: str, parts_of: Any) -> tuple[_Parts, int, _Footprint]:
        """Draw a footprint position (and turn) for a floor object by the placement rules."""
        pl, r, rng = self.spec.placement, self.spec.room, self.rng
        parts = parts_of()
        u = rng.random()
        if u < pl.against_wall_probability and r.walls:
            side = r.walls[int(rng.integers(len(r.walls)))]
            turns = _FACE_AWAY[side] if kind == "chair" else int(rng.integers(4))
            hx, hy = _half_extents(parts, turns)
            gap = _uniform(rng, pl.near_gap)
            axis, sign = _SIDES[side]
            x = _uniform(rng, (r.x[0] + hx, r.x[1] - hx)) if r.x[1] - r.x[0] > 2 * hx else 0.0
            y = _uniform(rng, (r.y[0] + hy, r.y[1] - hy)) if r.y[1] - r.y[0] > 2 * hy else 0.0
            if axis == 0:
                x = r.x[1] - gap - hx if sign > 0 else r.x[0] + gap + hx
            else:
                y = r.y[1] - gap - hy if sign > 0 else r.y[0] + gap + hy
            return parts, turns, _Footprint(x, y, hx, hy)
        if u < pl.against_wall_probability + pl.next_to_probability and self.floor_prints:
            _, akind, a = self.floor_prints[int(rng.integers(len(self.floor_prints)))]
            side = tuple(_SIDES)[int(rng.integers(4))]
            if kind == "chair" and akind == "table":
                turns = _FACE_AWAY[side]
            else:
                turns = int(rng.integers(4))
            hx, hy = _half_extents(parts, turns)
            gap = _uniform(rng, pl.near_gap)
            axis, sign = _SIDES[side]
            t = float(rng.uniform(-0.8, 0.8))
            if axis == 0:
                x, y = a.x + sign * (a.hx + gap + hx), a.y + t * (a.hy + hy)
            else:
                x, y = a.x + t * (a.hx + hx), a.y + sign * (a.hy + gap + hy)
            return parts, turns, _Footprint(x, y, hx, hy)
        turns = int(rng.integers(4))
        hx, hy = _half_extents(parts, turns)
        x = _uniform(rng, (min(r.x[0] + hx, r.x[1]), max(r.x[1] - hx, r.x[0])))
        y = _uniform(rng, (min(r.y[0] + hy, r.y[1]), max(r.y[1] - hy, r.y[0])))
        return parts, turns, _Footprint(x, y, hx, hy)

    def floor_object(self, kind: str, index: int, parts_of: Any, mass: Range, widen: str) -> None:
        """Place one table, chair or box on the floor, or raise `ConfigError`."""
        for _ in range(self.spec.placement.max_tries):
            parts, turns, fp = self._floor_pose(kind, parts_of)
            if self._fits_floor(fp):
                oid = self._new_id()
                boxes, cyl = _place(parts, fp.x, fp.y, 0.0, turns)
                m = _uniform(self.rng, mass)
                self.objects.append(OfficeObject(oid, kind, f"{kind}_{index}", -1, boxes, cyl, m))
                self.floor_prints.append((oid, kind, fp))
                self.on_top[oid] = []
                return
        raise ConfigError(
            f"could not place {kind}_{index} without overlaps in "
            f"{self.spec.placement.max_tries} tries; widen room.x / room.y, or lower the "
            f"upper end of {widen}.count."
        )

    def stacked_box(self, index: int, supports: list[int]) -> bool:
        """Place a box on one of `supports` (object ids); False if it fits on none of them."""
        if not supports:
            return False
        pl, rng = self.spec.placement, self.rng
        tops = {o.id: o.bounds for o in self.objects if o.id in supports}
        for _ in range(pl.max_tries):
            sid = supports[int(rng.integers(len(supports)))]
            lo, hi = tops[sid]
            cls = _box_class(self.spec.boxes, rng)
            parts = _box_parts(cls, rng)
            turns = int(rng.integers(2))
            hx, hy = _half_extents(parts, turns)
            room_x = (hi[0] - lo[0]) / 2 - hx - pl.min_clearance
            room_y = (hi[1] - lo[1]) / 2 - hy - pl.min_clearance
            if room_x < 0 or room_y < 0:
                continue
            fp = _Footprint(
                (lo[0] + hi[0]) / 2 + float(rng.uniform(-room_x, room_x)),
                (lo[1] + hi[1]) / 2 + float(rng.uniform(-room_y, room_y)),
                hx,
                hy,
            )
            if not all(fp.apart(o, pl.min_clearance) for o in self.on_top[sid]):
                continue
            oid = self._new_id()
            boxes, cyl = _place(parts, fp.x, fp.y, float(hi[2]), turns)
            m = _uniform(rng, cls.mass)
            self.objects.append(OfficeObject(oid, "box", f"box_{index}", sid, boxes, cyl, m))
            self.on_top[sid].append(fp)
            self.on_top[oid] = []
            return True
        return False  # no top has room left: the box goes to the floor


def sample_office_scene(spec: OfficeSpec, rng: np.random.Generator) -> OfficeScene:
    """Sample one office scene with its ground-truth labels.

    Object ids: 0 the floor, then the walls in the order of ``spec.room.walls``, then tables,
    chairs, floor boxes, boxes on tables and boxes on boxes.

    Args:
        spec: The office world.
        rng: The random stream; the same seed gives the same scene.

    Raises:
        InputError: If `spec` is not an `OfficeSpec` or `rng` not a `numpy.random.Generator`.
        ConfigError: If an object cannot be placed within ``spec.placement.max_tries`` tries,
            naming the range to widen.
    """
    if not isinstance(spec, OfficeSpec):
        raise InputError(f"spec must be an OfficeSpec (from load_office()), got {spec!r}.")
    if not isinstance(rng, np.random.Generator):
        raise InputError(
            f"rng must be a numpy.random.Generator (np.random.default_rng(seed)), got {rng!r}."
        )
    s = _Sampler(spec, rng)
    s.room()
    counts = {
        name: int(rng.integers(r[0], r[1] + 1))
        for name, r in (
            ("tables", spec.tables.count),
            ("chairs", spec.chairs.count),
            ("boxes", spec.boxes.count),
        )
    }
    for i in range(counts["tables"]):
        s.floor_object(
            "table", i, lambda: _table_parts(spec.tables, rng), spec.tables.mass, "tables"
        )
    for i in range(counts["chairs"]):
        s.floor_object(
            "chair", i, lambda: _chair_parts(spec.chairs, rng), spec.chairs.mass, "chairs"
        )
    b = spec.boxes
    modes = rng.choice(
        3,
        size=counts["boxes"],
        p=[
            1.0 - b.on_table_probability - b.on_box_probability,
            b.on_table_probability,
            b.on_box_probability,
        ],
    )
    order = np.argsort(modes, kind="stable")
    floor_boxes: list[int] = []
    for i in order:
        mode = int(modes[i])
        if mode == 1:
            tables = [o.id for o in s.objects if o.kind == "table"]
            if s.stacked_box(int(i), tables):
                continue
        elif mode == 2:
            free = [j for j in floor_boxes if not s.on_top[j]]
            if s.stacked_box(int(i), free):
                continue
        cls = _box_class(b, rng)
        s.floor_object("box", int(i), lambda c=cls: _box_parts(c, rng), cls.mass, "boxes")
        floor_boxes.append(s.objects[-1].id)
    pose = (spec.robot.x, spec.robot.y, spec.robot.yaw)
    return assemble_office_scene(s.objects, spec.labels, pose)


def sample_office_scenes(spec: OfficeSpec, n: int, seed: int) -> list[OfficeScene]:
    """Sample `n` scenes, each from its own stream spawned from `seed` (`np.random.SeedSequence`).

    Args:
        spec: The office world.
        n: How many scenes (>= 1).
        seed: The root seed (an integer >= 0).

    Returns:
        The scenes; scene i depends only on `seed` and i.
    """
    n = check_count("n", n)
    seed = check_count("seed", seed, minimum=0)
    streams = np.random.SeedSequence(seed).spawn(n)
    return [sample_office_scene(spec, np.random.default_rng(ss)) for ss in streams]


register_world(
    WorldKind(
        name="office", label="office", load_world=load_office, simulate=sample_office_scene, order=3
    )
)
