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

Labels, in the order of `LABELS`, by the thesis's manual labelling criteria (section 2.3.3):

- The floor and the walls carry no label (all false).
- All segments of an object share its labels: labels are per object.
- Pushable in a direction d unless blocked: another object (a wall included, the floor and the
  object's own load excluded) lies on the d side, its footprint's gap along d is below
  ``labels.push_clearance`` (0.15 m, our choice: about one gripper span, the room the hand needs
  beside an object and a short push step) and its footprint's extent across d overlaps this one's
  by more than 0 m, and their height ranges overlap. Footprints are the object's parts projected
  on the floor; gap and overlap are measured on their projections along d and across it.
- An object standing on another object (a table top or a box) is pushable every way: the
  thesis's "physically feasible primitive", even though it may fall off. A table, chair or box
  with something on it is still pushable unless blocked.
- Liftable when nothing stands on it, its mass is at most ``labels.max_lift_mass`` (1.8 kg, the
  PR2's payload, thesis section 2.6) and its largest horizontal extent at most
  ``labels.max_lift_size`` (0.6 m, our choice: what two arms can hold). Tables (15-30 kg) are not
  liftable; chairs (1.0-1.8 kg) and boxes are, unless something is on them or they are too big or
  heavy.
- Graspable when some part is thinner than ``labels.gripper_span`` (0.15 m, the thesis's PR2
  gripper) across which the fingers close horizontally: a box whose smaller horizontal extent is
  below the span, a chair's back or legs, a table's legs or a thin pedestal. Our choice: a table
  top's edge (2-4 cm thick) does not count, since the fingers would have to close vertically
  round a plate whose far side they cannot reach; a four-legged table is graspable by its legs,
  a pedestal table only if the pedestal's diameter is below the span.

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
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from probaff._checks import check_count, check_finite, check_positive, check_shape
from probaff.affordance_labels import LABELS, label_index
from probaff.errors import ConfigError, InputError
from probaff.sim.config import (
    _check_spec,
    _count,
    _field,
    _load_root,
    _mapping,
    _no_extra,
    _number,
    _range,
    _take,
)
from probaff.sim.geometry import convex_penetration, rect_disc_penetration
from probaff.sim.primitives import PrimitiveScene

__all__ = [
    "KINDS",
    "LABELS",
    "OfficeBoxClass",
    "OfficeBoxesSpec",
    "OfficeChairSpec",
    "OfficeLabelRules",
    "OfficeObject",
    "OfficePlacementSpec",
    "OfficeRobotSpec",
    "OfficeRoomSpec",
    "OfficeScene",
    "OfficeSpec",
    "OfficeTableSpec",
    "assemble_office_scene",
    "label_index",
    "load_office",
    "office_labels",
    "sample_office_scene",
    "sample_office_scenes",
]

KINDS = ("floor", "wall", "table", "chair", "box")
_WALLS = ("+x", "-x", "+y", "-y")
# Push directions in the robot frame, in the order of LABELS[:4].
_ROBOT_DIRECTIONS = np.array([[1.0, 0.0], [-1.0, 0.0], [0.0, 1.0], [0.0, -1.0]])

Range = tuple[float, float]


# ----------------------------------------------------------------------------------- the spec


@dataclass(frozen=True)
class OfficeRoomSpec:
    """The room: floor extent (m, world x and y), walls (height, thickness) and floor slab."""

    x: Range
    y: Range
    wall_height: float
    wall_thickness: float
    floor_thickness: float
    walls: tuple[str, ...]

    def __post_init__(self) -> None:
        _check_spec(self, positive=("wall_height", "wall_thickness", "floor_thickness"))
        for name in ("x", "y"):
            lo, hi = getattr(self, name)
            if not (math.isfinite(lo) and math.isfinite(hi) and hi > lo):
                raise ConfigError(
                    f"OfficeRoomSpec.{name} must be a finite [low, high], low < high."
                )
        for w in self.walls:
            if w not in _WALLS:
                raise ConfigError(f"OfficeRoomSpec.walls: unknown side {w!r}; use {list(_WALLS)}.")
        if len(set(self.walls)) != len(self.walls):
            raise ConfigError("OfficeRoomSpec.walls lists a side twice; name each side once.")


@dataclass(frozen=True)
class OfficeRobotSpec:
    """Where the robot stands: ``x, y`` (m, world), `yaw` (rad) and the `keep_out` radius (m)."""

    x: float
    y: float
    yaw: float
    keep_out: float

    def __post_init__(self) -> None:
        try:
            check_finite("OfficeRobotSpec pose", [self.x, self.y, self.yaw])
        except InputError as exc:
            raise ConfigError(str(exc)) from None
        _check_spec(self, nonneg=("keep_out",))


def _check_count_range(where: str, value: object) -> None:
    """Check that `value` is a ``(low, high)`` pair of integers, 0 <= low <= high."""
    if not isinstance(value, tuple) or len(value) != 2:
        raise ConfigError(f"{where} must be a (low, high) pair of counts, got {value!r}.")
    lo, hi = (_count(f"{where}[{i}]", v, minimum=0) for i, v in enumerate(value))
    if lo > hi:
        raise ConfigError(f"{where} has low {lo} > high {hi}; swap them.")


@dataclass(frozen=True)
class OfficeTableSpec:
    """Table ranges (m, kg); see ``worlds/office.yaml``."""

    count: tuple[int, int]
    top_length: Range
    top_depth: Range
    top_thickness: Range
    height: Range
    leg_size: Range
    leg_inset: float
    pedestal_probability: float
    pedestal_radius: Range
    mass: Range

    def __post_init__(self) -> None:
        _check_count_range(f"{type(self).__name__}.count", self.count)
        _check_spec(
            self,
            positive=(
                "top_length",
                "top_depth",
                "top_thickness",
                "height",
                "leg_size",
                "pedestal_radius",
                "mass",
            ),
            nonneg=("leg_inset", "pedestal_probability"),
        )


@dataclass(frozen=True)
class OfficeChairSpec:
    """Chair ranges (m, kg); the chair faces its own +x, its back at its -x edge."""

    count: tuple[int, int]
    seat_width: Range
    seat_depth: Range
    seat_height: Range
    seat_thickness: Range
    back_height: Range
    back_thickness: Range
    leg_size: Range
    cylinder_leg_probability: float
    mass: Range

    def __post_init__(self) -> None:
        _check_count_range(f"{type(self).__name__}.count", self.count)
        _check_spec(
            self,
            positive=(
                "seat_width",
                "seat_depth",
                "seat_height",
                "seat_thickness",
                "back_height",
                "back_thickness",
                "leg_size",
                "mass",
            ),
            nonneg=("cylinder_leg_probability",),
        )


@dataclass(frozen=True)
class OfficeBoxClass:
    """One size class of boxes: a relative `weight` and ranges of extents (m) and mass (kg)."""

    name: str
    weight: float
    length: Range
    width: Range
    height: Range
    mass: Range

    def __post_init__(self) -> None:
        _check_spec(self, positive=("weight", "length", "width", "height", "mass"))


@dataclass(frozen=True)
class OfficeBoxesSpec:
    """How many boxes, where they stand (probabilities) and their size classes."""

    count: tuple[int, int]
    on_table_probability: float
    on_box_probability: float
    classes: tuple[OfficeBoxClass, ...]

    def __post_init__(self) -> None:
        _check_count_range(f"{type(self).__name__}.count", self.count)
        _check_spec(self, nonneg=("on_table_probability", "on_box_probability"))
        if self.on_table_probability + self.on_box_probability > 1.0 + 1e-12:
            raise ConfigError(
                "OfficeBoxesSpec: on_table_probability + on_box_probability must be <= 1."
            )
        if not self.classes:
            raise ConfigError("OfficeBoxesSpec.classes is empty; give at least one box class.")


@dataclass(frozen=True)
class OfficePlacementSpec:
    """Rejection-sampling rules for placing objects; see the module docstring."""

    min_clearance: float
    against_wall_probability: float
    next_to_probability: float
    near_gap: Range
    max_tries: int

    def __post_init__(self) -> None:
        _check_spec(
            self,
            positive=("min_clearance", "near_gap"),
            nonneg=("against_wall_probability", "next_to_probability"),
            counts=("max_tries",),
        )
        if self.against_wall_probability + self.next_to_probability > 1.0 + 1e-12:
            raise ConfigError(
                "OfficePlacementSpec: against_wall_probability + next_to_probability must be <= 1."
            )
        if self.near_gap[0] < self.min_clearance:
            raise ConfigError(
                f"OfficePlacementSpec.near_gap low {self.near_gap[0]} is below min_clearance "
                f"{self.min_clearance}; raise it."
            )


@dataclass(frozen=True)
class OfficeLabelRules:
    """Thresholds of the label rules (m, kg); see the module docstring for each one's source."""

    gripper_span: float = 0.15
    push_clearance: float = 0.15
    max_lift_mass: float = 1.8
    max_lift_size: float = 0.6

    def __post_init__(self) -> None:
        _check_spec(
            self, positive=("gripper_span", "push_clearance", "max_lift_mass", "max_lift_size")
        )


@dataclass(frozen=True)
class OfficeSpec:
    """An office world (``worlds/office.yaml``)."""

    room: OfficeRoomSpec
    robot: OfficeRobotSpec
    tables: OfficeTableSpec
    chairs: OfficeChairSpec
    boxes: OfficeBoxesSpec
    placement: OfficePlacementSpec
    labels: OfficeLabelRules


def _probability(where: str, value: Any) -> float:
    v = _number(where, value, nonneg=True)
    if v > 1.0:
        raise ConfigError(f"{where} must be a probability in [0, 1], got {value!r}.")
    return v


def _count_range(where: str, value: Any) -> tuple[int, int]:
    if not isinstance(value, (list, tuple)) or len(value) != 2:
        raise ConfigError(f"{where} must be a [low, high] pair of counts, got {value!r}.")
    lo, hi = (_count(f"{where}[{i}]", v, minimum=0) for i, v in enumerate(value))
    if lo > hi:
        raise ConfigError(f"{where} has low {lo} > high {hi}; swap them.")
    return (lo, hi)


def _positive_range(where: str, table: dict[str, Any], key: str) -> Range:
    return _range(f"{where}.{key}", _take(where, table, key), positive=True)


def _load_tables(w: str, raw: dict[str, Any]) -> OfficeTableSpec:
    s = f"{w}:tables"
    t = _mapping(s, _take(w, raw, "tables"))
    keys = {
        "count",
        "top_length",
        "top_depth",
        "top_thickness",
        "height",
        "leg_size",
        "leg_inset",
        "pedestal_probability",
        "pedestal_radius",
        "mass",
    }
    _no_extra(s, t, keys)
    spec = OfficeTableSpec(
        count=_count_range(f"{s}.count", _take(s, t, "count")),
        top_length=_positive_range(s, t, "top_length"),
        top_depth=_positive_range(s, t, "top_depth"),
        top_thickness=_positive_range(s, t, "top_thickness"),
        height=_positive_range(s, t, "height"),
        leg_size=_positive_range(s, t, "leg_size"),
        leg_inset=_field(w, "tables", t, "leg_inset", nonneg=True),
        pedestal_probability=_probability(
            f"{s}.pedestal_probability", _take(s, t, "pedestal_probability")
        ),
        pedestal_radius=_positive_range(s, t, "pedestal_radius"),
        mass=_positive_range(s, t, "mass"),
    )
    if spec.top_thickness[1] >= spec.height[0]:
        raise ConfigError(f"{s}.top_thickness must stay below the smallest height.")
    if 2 * (spec.leg_inset + spec.leg_size[1]) >= min(spec.top_length[0], spec.top_depth[0]):
        raise ConfigError(f"{s}: legs and inset do not fit under the smallest top; shrink them.")
    if 2 * spec.pedestal_radius[1] >= min(spec.top_length[0], spec.top_depth[0]):
        raise ConfigError(f"{s}.pedestal_radius is too large for the smallest top; shrink it.")
    return spec


def _load_chairs(w: str, raw: dict[str, Any]) -> OfficeChairSpec:
    s = f"{w}:chairs"
    c = _mapping(s, _take(w, raw, "chairs"))
    keys = {
        "count",
        "seat_width",
        "seat_depth",
        "seat_height",
        "seat_thickness",
        "back_height",
        "back_thickness",
        "leg_size",
        "cylinder_leg_probability",
        "mass",
    }
    _no_extra(s, c, keys)
    spec = OfficeChairSpec(
        count=_count_range(f"{s}.count", _take(s, c, "count")),
        seat_width=_positive_range(s, c, "seat_width"),
        seat_depth=_positive_range(s, c, "seat_depth"),
        seat_height=_positive_range(s, c, "seat_height"),
        seat_thickness=_positive_range(s, c, "seat_thickness"),
        back_height=_positive_range(s, c, "back_height"),
        back_thickness=_positive_range(s, c, "back_thickness"),
        leg_size=_positive_range(s, c, "leg_size"),
        cylinder_leg_probability=_probability(
            f"{s}.cylinder_leg_probability", _take(s, c, "cylinder_leg_probability")
        ),
        mass=_positive_range(s, c, "mass"),
    )
    if spec.seat_thickness[1] >= spec.seat_height[0]:
        raise ConfigError(f"{s}.seat_thickness must stay below the smallest seat_height.")
    if spec.back_height[0] <= spec.seat_height[1]:
        raise ConfigError(f"{s}.back_height must exceed the largest seat_height.")
    smallest_seat = min(spec.seat_width[0], spec.seat_depth[0])
    if 2 * max(spec.leg_size[1], spec.back_thickness[1]) >= smallest_seat:
        raise ConfigError(f"{s}: legs or back are too thick for the smallest seat; shrink them.")
    return spec


def _load_boxes(w: str, raw: dict[str, Any]) -> OfficeBoxesSpec:
    s = f"{w}:boxes"
    b = _mapping(s, _take(w, raw, "boxes"))
    _no_extra(s, b, {"count", "on_table_probability", "on_box_probability", "classes"})
    classes_raw = _take(s, b, "classes")
    if not isinstance(classes_raw, list) or not classes_raw:
        raise ConfigError(f"{s}.classes must be a non-empty list of box classes.")
    classes = []
    for i, cr in enumerate(classes_raw):
        cw = f"{s}.classes[{i}]"
        c = _mapping(cw, cr)
        _no_extra(cw, c, {"name", "weight", "length", "width", "height", "mass"})
        classes.append(
            OfficeBoxClass(
                name=str(_take(cw, c, "name")),
                weight=_number(f"{cw}.weight", _take(cw, c, "weight"), positive=True),
                length=_positive_range(cw, c, "length"),
                width=_positive_range(cw, c, "width"),
                height=_positive_range(cw, c, "height"),
                mass=_positive_range(cw, c, "mass"),
            )
        )
    p_table = _probability(f"{s}.on_table_probability", _take(s, b, "on_table_probability"))
    p_box = _probability(f"{s}.on_box_probability", _take(s, b, "on_box_probability"))
    if p_table + p_box > 1.0:
        raise ConfigError(f"{s}: on_table_probability + on_box_probability must be <= 1.")
    return OfficeBoxesSpec(
        count=_count_range(f"{s}.count", _take(s, b, "count")),
        on_table_probability=p_table,
        on_box_probability=p_box,
        classes=tuple(classes),
    )


def load_office(path: Path | None = None) -> OfficeSpec:
    """Load and validate the office world (``worlds/office.yaml``).

    Args:
        path: Another office file; defaults to the one in `probaff.sim.config.worlds_dir()`.

    Raises:
        ConfigError: For a missing file, malformed YAML, or a missing, unknown or out-of-range
            field, naming the file and the field.
    """
    raw, w, _ = _load_root(path, "office.yaml")
    _no_extra(w, raw, {"room", "robot", "tables", "chairs", "boxes", "placement", "labels"})
    rr = _mapping(f"{w}:room", _take(w, raw, "room"))
    _no_extra(
        f"{w}:room",
        rr,
        {"x", "y", "wall_height", "wall_thickness", "floor_thickness", "walls"},
    )
    walls = _take(f"{w}:room", rr, "walls")
    if not isinstance(walls, list) or not all(isinstance(v, str) for v in walls):
        raise ConfigError(f"{w}:room.walls must be a list of sides from {list(_WALLS)}.")
    x, y = (_range(f"{w}:room.{k}", _take(f"{w}:room", rr, k)) for k in ("x", "y"))
    if x[1] <= x[0] or y[1] <= y[0]:
        raise ConfigError(f"{w}:room.x and room.y must each have low < high.")
    bad = [v for v in walls if v not in _WALLS]
    if bad:
        raise ConfigError(f"{w}:room.walls: unknown side(s) {bad}; use {list(_WALLS)}.")
    room = OfficeRoomSpec(
        x=x,
        y=y,
        wall_height=_field(w, "room", rr, "wall_height", positive=True),
        wall_thickness=_field(w, "room", rr, "wall_thickness", positive=True),
        floor_thickness=_field(w, "room", rr, "floor_thickness", positive=True),
        walls=tuple(walls),
    )
    ro = _mapping(f"{w}:robot", _take(w, raw, "robot"))
    _no_extra(f"{w}:robot", ro, {"pose", "keep_out"})
    pose = _take(f"{w}:robot", ro, "pose")
    if not isinstance(pose, list) or len(pose) != 3:
        raise ConfigError(f"{w}:robot.pose must be [x, y, yaw_deg], got {pose!r}.")
    px, py, pyaw = (_number(f"{w}:robot.pose[{i}]", v) for i, v in enumerate(pose))
    robot = OfficeRobotSpec(
        x=px,
        y=py,
        yaw=math.radians(pyaw),
        keep_out=_field(w, "robot", ro, "keep_out", nonneg=True),
    )
    pl = _mapping(f"{w}:placement", _take(w, raw, "placement"))
    s = f"{w}:placement"
    _no_extra(
        s,
        pl,
        {
            "min_clearance",
            "against_wall_probability",
            "next_to_probability",
            "near_gap",
            "max_tries",
        },
    )
    placement = OfficePlacementSpec(
        min_clearance=_field(w, "placement", pl, "min_clearance", positive=True),
        against_wall_probability=_probability(
            f"{s}.against_wall_probability", _take(s, pl, "against_wall_probability")
        ),
        next_to_probability=_probability(
            f"{s}.next_to_probability", _take(s, pl, "next_to_probability")
        ),
        near_gap=_positive_range(s, pl, "near_gap"),
        max_tries=_count(f"{s}.max_tries", _take(s, pl, "max_tries")),
    )
    lr = _mapping(f"{w}:labels", _take(w, raw, "labels"))
    _no_extra(
        f"{w}:labels", lr, {"gripper_span", "push_clearance", "max_lift_mass", "max_lift_size"}
    )
    labels = OfficeLabelRules(
        gripper_span=_field(w, "labels", lr, "gripper_span", positive=True),
        push_clearance=_field(w, "labels", lr, "push_clearance", positive=True),
        max_lift_mass=_field(w, "labels", lr, "max_lift_mass", positive=True),
        max_lift_size=_field(w, "labels", lr, "max_lift_size", positive=True),
    )
    return OfficeSpec(
        room=room,
        robot=robot,
        tables=_load_tables(w, raw),
        chairs=_load_chairs(w, raw),
        boxes=_load_boxes(w, raw),
        placement=placement,
        labels=labels,
    )


# -------------------------------------------------------------------------------- the objects


def _floats(name: str, value: object) -> np.ndarray:
    try:
        return np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise InputError(f"{name} must hold numbers, got {value!r}.") from None


def _parts(name: str, value: object, columns: int) -> np.ndarray:
    arr = _floats(name, value)
    if arr.size == 0:
        arr = arr.reshape(0, columns)
    check_shape(name, arr, (None, columns))
    check_finite(name, arr)
    return arr


@dataclass(frozen=True, eq=False)
class OfficeObject:
    """One object of an office scene and its solid parts.

    Attributes:
        id: Object id (>= 0), unique in its scene; the ids of its primitives.
        kind: One of `KINDS`.
        name: A readable name, e.g. ``"table_0"``.
        support: Id of the object it stands on, or -1 for the floor (and for the floor and
            walls themselves).
        boxes: (P, 7) world frame ``(cx, cy, cz, sx, sy, sz, yaw)``, its box parts (m, rad).
        cylinders: (Q, 5) world frame ``(cx, cy, cz, radius, height)``, its cylinder parts.
        mass: Mass (kg, >= 0; 0 for the fixed floor and walls).

    Raises:
        InputError: For an unknown kind, a bad id or support, malformed parts or no parts.
    """

    id: int
    kind: str
    name: str
    support: int = -1
    boxes: np.ndarray = field(default_factory=lambda: np.zeros((0, 7)))
    cylinders: np.ndarray = field(default_factory=lambda: np.zeros((0, 5)))
    mass: float = 0.0

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise InputError(f"kind: unknown object kind {self.kind!r}; use one of {list(KINDS)}.")
        object.__setattr__(self, "id", check_count("id", self.id, minimum=0))
        object.__setattr__(self, "support", check_count("support", self.support, minimum=-1))
        if self.support == self.id:
            raise InputError(f"support: object {self.id} cannot stand on itself.")
        boxes = _parts("boxes", self.boxes, 7)
        cylinders = _parts("cylinders", self.cylinders, 5)
        if len(boxes) + len(cylinders) == 0:
            raise InputError(
                f"object {self.id} ({self.name}) has no parts; give a box or cylinder."
            )
        if np.any(boxes[:, 3:6] <= 0) or np.any(cylinders[:, 3:5] <= 0):
            raise InputError(f"object {self.id} ({self.name}): part extents must be > 0.")
        check_positive("mass", self.mass, allow_zero=True)
        object.__setattr__(self, "boxes", boxes)
        object.__setattr__(self, "cylinders", cylinders)
        object.__setattr__(self, "mass", float(self.mass))

    @property
    def bounds(self) -> np.ndarray:
        """(2, 3) world frame: the lower and upper corners of its axis-aligned bounding box."""
        xy = _xy_points(self)
        z0, z1 = self.z_range
        return np.array([[*xy.min(axis=0), z0], [*xy.max(axis=0), z1]])

    @property
    def z_range(self) -> tuple[float, float]:
        """Lowest and highest z of its parts (m, world)."""
        zs = np.concatenate(
            [
                self.boxes[:, 2] - self.boxes[:, 5] / 2,
                self.boxes[:, 2] + self.boxes[:, 5] / 2,
                self.cylinders[:, 2] - self.cylinders[:, 4] / 2,
                self.cylinders[:, 2] + self.cylinders[:, 4] / 2,
            ]
        )
        return float(zs.min()), float(zs.max())

    @property
    def grasp_width(self) -> float:
        """Thinnest horizontal width of its parts (m): min(sx, sy) of a box, 2 r of a cylinder."""
        widths = np.concatenate([self.boxes[:, 3:5].min(axis=1), 2 * self.cylinders[:, 3]])
        return float(widths.min())


def _box_corners(boxes: np.ndarray) -> np.ndarray:
    """(4 P, 2) world xy: the footprint corners of the boxes `boxes` (P, 7)."""
    signs = np.array([[1, 1], [1, -1], [-1, 1], [-1, -1]], dtype=np.float64)
    c, s = np.cos(boxes[:, 6:7]), np.sin(boxes[:, 6:7])
    u = signs[None, :, 0] * boxes[:, 3:4] / 2
    v = signs[None, :, 1] * boxes[:, 4:5] / 2
    x = boxes[:, 0:1] + c * u - s * v
    y = boxes[:, 1:2] + s * u + c * v
    return np.stack([x, y], axis=-1).reshape(-1, 2)


def _xy_points(obj: OfficeObject) -> np.ndarray:
    """(M, 2) world xy: its box corners and the 4 axis-extreme points of each cylinder."""
    axes = np.array([[1, 0], [-1, 0], [0, 1], [0, -1]], dtype=np.float64)
    cyl = obj.cylinders
    round_pts = (cyl[:, None, :2] + cyl[:, None, 3:4] * axes[None]).reshape(-1, 2)
    return np.concatenate([_box_corners(obj.boxes), round_pts])


def _projection(obj: OfficeObject, d: np.ndarray) -> tuple[float, float]:
    """Interval (m) of the object's footprint projected on the unit xy direction `d` (2,)."""
    centre = obj.cylinders[:, :2] @ d
    r = obj.cylinders[:, 3]
    vals = np.concatenate([_box_corners(obj.boxes) @ d, centre - r, centre + r])
    return float(vals.min()), float(vals.max())


def _blocks(
    k: int, m: int, axis: int, sign: int, iv: np.ndarray, z: np.ndarray, clearance: float
) -> bool:
    """Whether object `m` blocks pushing object `k` along ``sign`` times robot axis `axis`.

    Args:
        k: Row of the pushed object.
        m: Row of the other object.
        axis: 0 for the robot's x (forward/backward), 1 for its y (left/right).
        sign: +1 (forward, left) or -1 (backward, right).
        iv: (K, 2, 2) footprint intervals ``(lo, hi)`` of each object projected on the robot's
            x and y axes (m, world xy projected on the robot's axes).
        z: (K, 2) height range ``(lo, hi)`` of each object (m).
        clearance: The push clearance (m).
    """
    if min(z[k, 1], z[m, 1]) - max(z[k, 0], z[m, 0]) <= 0:
        return False
    lo, hi = sorted(sign * iv[k, axis])
    olo, ohi = sorted(sign * iv[m, axis])
    if olo + ohi <= lo + hi or olo - hi >= clearance:  # not on that side, or far enough
        return False
    (plo, phi), (qlo, qhi) = iv[k, 1 - axis], iv[m, 1 - axis]
    return bool(min(phi, qhi) - max(plo, qlo) > 0)


def office_labels(
    objects: Sequence[OfficeObject], rules: OfficeLabelRules, robot_yaw: float = 0.0
) -> np.ndarray:
    """Ground-truth labels of every object by the rules of the module docstring.

    Args:
        objects: The K objects of a scene (ids unique, supports among them or -1).
        rules: The thresholds.
        robot_yaw: The robot's yaw in the world (rad); push directions are in its frame.

    Returns:
        (K, 6) bool, row k for ``objects[k]``, columns in the order of `LABELS`.

    Raises:
        InputError: For objects that do not form a consistent scene (see
            `assemble_office_scene`) or a non-finite yaw.
    """
    _check_objects(objects)
    yaw = _floats("robot_yaw", robot_yaw)
    check_shape("robot_yaw", yaw, ())
    check_finite("robot_yaw", yaw)
    c, s = math.cos(float(yaw)), math.sin(float(yaw))
    world_dirs = _ROBOT_DIRECTIONS @ np.array([[c, s], [-s, c]])
    children: dict[int, list[int]] = {o.id: [] for o in objects}
    for o in objects:
        if o.support >= 0:
            children[o.support].append(o.id)
    iv = np.array([[_projection(o, a) for a in world_dirs[[0, 2]]] for o in objects])
    z = np.array([o.z_range for o in objects])
    labels = np.zeros((len(objects), len(LABELS)), dtype=bool)
    for k, o in enumerate(objects):
        if o.kind in ("floor", "wall"):
            continue
        if o.support >= 0:
            labels[k, :4] = True
        else:
            load = _descendants(o.id, children)
            others = [
                m
                for m, b in enumerate(objects)
                if b.kind != "floor" and b.id != o.id and b.id not in load
            ]
            for j in range(4):
                axis, sign = j // 2, 1 - 2 * (j % 2)
                labels[k, j] = not any(
                    _blocks(k, m, axis, sign, iv, z, rules.push_clearance) for m in others
                )
        lo, hi = o.bounds
        size = float(max(hi[0] - lo[0], hi[1] - lo[1]))
        labels[k, 4] = (
            not children[o.id] and o.mass <= rules.max_lift_mass and size <= rules.max_lift_size
        )
        labels[k, 5] = o.grasp_width < rules.gripper_span
    return labels


def _descendants(root: int, children: dict[int, list[int]]) -> set[int]:
    out: set[int] = set()
    todo = list(children[root])
    while todo:
        i = todo.pop()
        if i not in out:
            out.add(i)
            todo.extend(children[i])
    return out


def _check_objects(objects: Sequence[OfficeObject]) -> None:
    """Raise `InputError` unless `objects` form a physically consistent scene.

    Ids are unique; every support is in the scene, is neither the floor nor a wall (objects on
    the floor take -1) and the supports form no cycle; the floor and walls stand on nothing;
    no two objects' solids interpenetrate; an object on the floor has its lowest point on the
    floor's top (z = 0) and its footprint on a floor object of the scene, if there is one;
    an object on another rests on one of that object's top faces.
    """
    if isinstance(objects, (str, bytes)) or not isinstance(objects, Sequence):
        raise InputError(f"objects must be a list of OfficeObject, got {type(objects).__name__}.")
    if len(objects) == 0:
        raise InputError("objects is empty; give at least one OfficeObject.")
    for i, o in enumerate(objects):
        if not isinstance(o, OfficeObject):
            raise InputError(f"objects[{i}] must be an OfficeObject, got {type(o).__name__}.")
    ids = [o.id for o in objects]
    if len(set(ids)) != len(ids):
        raise InputError("objects: object ids must be unique.")
    by_id = {o.id: o for o in objects}
    for o in objects:
        if o.support < 0:
            continue
        if o.support not in by_id:
            raise InputError(
                f"objects: {o.name} stands on object {o.support}, which is not in the scene."
            )
        base = by_id[o.support]
        if o.kind in _STRUCTURE:
            raise InputError(
                f"objects: {o.name} (id {o.id}) is a {o.kind} and stands on nothing; give it "
                "support -1."
            )
        if base.kind in _STRUCTURE:
            raise InputError(
                f"objects: {o.name} (id {o.id}) has support {base.id}, the {base.kind} "
                f"{base.name}; an object standing on the floor takes support -1, and nothing "
                "stands on a wall."
            )
    _check_support_cycles(objects, by_id)
    _check_overlaps(objects)
    _check_resting(objects, by_id)


_STRUCTURE = ("floor", "wall")
_OVERLAP_TOL = 1e-6  # m; solids may interpenetrate this much (faces in contact)
_REST_TOL = 1e-3  # m; an object rests on a surface whose height is this close to its bottom


def _check_support_cycles(objects: Sequence[OfficeObject], by_id: dict[int, OfficeObject]) -> None:
    """Raise `InputError` if following supports from some object comes back to it."""
    done: set[int] = set()
    for o in objects:
        chain: list[int] = []
        oid = o.id
        while oid >= 0 and oid not in done:
            if oid in chain:
                loop = [*chain[chain.index(oid) :], oid]
                names = " on ".join(f"{by_id[i].name} (id {i})" for i in loop)
                raise InputError(
                    f"objects: the supports form a cycle, {names}; every chain of supports "
                    "must end on the floor (support -1)."
                )
            chain.append(oid)
            oid = by_id[oid].support
        done.update(chain)


def _solids(objects: Sequence[OfficeObject]) -> tuple[np.ndarray, ...]:
    """Every part of every object: owner row, kind (0 box, 1 cylinder), row, bounds (P, 6)."""
    owner, kind, row, lo, hi = [], [], [], [], []
    for k, o in enumerate(objects):
        for r, b in enumerate(o.boxes):
            xy = _box_corners(b[None])
            owner.append(k)
            kind.append(0)
            row.append(r)
            lo.append([*xy.min(axis=0), b[2] - b[5] / 2])
            hi.append([*xy.max(axis=0), b[2] + b[5] / 2])
        for r, c in enumerate(o.cylinders):
            owner.append(k)
            kind.append(1)
            row.append(r)
            lo.append([c[0] - c[3], c[1] - c[3], c[2] - c[4] / 2])
            hi.append([c[0] + c[3], c[1] + c[3], c[2] + c[4] / 2])
    return (
        np.array(owner, dtype=np.int64),
        np.array(kind, dtype=np.int64),
        np.array(row, dtype=np.int64),
        np.array(lo, dtype=np.float64).reshape(-1, 3),
        np.array(hi, dtype=np.float64).reshape(-1, 3),
    )


def _footprint_depth(a: OfficeObject, ka: int, ra: int, b: OfficeObject, kb: int, rb: int) -> float:
    """Depth (m) by which the footprints of part `ra` of `a` and part `rb` of `b` overlap."""
    if ka == 0 and kb == 0:
        return convex_penetration(
            _box_corners(a.boxes[ra : ra + 1])[[0, 1, 3, 2]],
            _box_corners(b.boxes[rb : rb + 1])[[0, 1, 3, 2]],
        )
    if ka == 1 and kb == 1:
        p, q = a.cylinders[ra], b.cylinders[rb]
        return float(p[3] + q[3] - math.hypot(p[0] - q[0], p[1] - q[1]))
    box, cyl = (a.boxes[ra], b.cylinders[rb]) if ka == 0 else (b.boxes[rb], a.cylinders[ra])
    return rect_disc_penetration(box[:2], (box[3], box[4]), box[6], cyl[:2], cyl[3])


def _check_overlaps(objects: Sequence[OfficeObject]) -> None:
    """Raise `InputError` naming the first two objects whose solids interpenetrate.

    Parts are upright prisms (boxes with a yaw, vertical cylinders), so two parts
    interpenetrate exactly when their height ranges and their footprints both overlap; the
    depth is the smaller of the two overlaps. Bounding boxes pick the candidate pairs first.
    """
    owner, kind, row, lo, hi = _solids(objects)
    i, j = np.triu_indices(len(owner), k=1)
    cand = owner[i] != owner[j]
    i, j = i[cand], j[cand]
    reach = np.minimum(hi[i], hi[j]) - np.maximum(lo[i], lo[j])  # (M, 3) overlap per axis
    cand = np.all(reach > _OVERLAP_TOL, axis=1)
    for a, b, dz in zip(i[cand], j[cand], reach[cand, 2], strict=True):
        oa, ob = objects[owner[a]], objects[owner[b]]
        depth = min(float(dz), _footprint_depth(oa, kind[a], row[a], ob, kind[b], row[b]))
        if depth > _OVERLAP_TOL:
            raise InputError(
                f"objects: {oa.name} (id {oa.id}) and {ob.name} (id {ob.id}) overlap by "
                f"{1000 * depth:.1f} mm; move them apart, or stand one on the other (its "
                "bottom on the other's top, its support set to the other's id)."
            )


def _on_part(x: float, y: float, z: float, obj: OfficeObject) -> bool:
    """Whether the point (x, y, z) lies on a top face of a part of `obj` (within tolerances)."""
    for b in obj.boxes:
        c, s = math.cos(b[6]), math.sin(b[6])
        u, v = c * (x - b[0]) + s * (y - b[1]), -s * (x - b[0]) + c * (y - b[1])
        top = b[2] + b[5] / 2
        if abs(z - top) <= _REST_TOL and abs(u) <= b[3] / 2 and abs(v) <= b[4] / 2:
            return True
    for cy in obj.cylinders:
        top = cy[2] + cy[4] / 2
        if abs(z - top) <= _REST_TOL and math.hypot(x - cy[0], y - cy[1]) <= cy[3]:
            return True
    return False


def _check_resting(objects: Sequence[OfficeObject], by_id: dict[int, OfficeObject]) -> None:
    """Raise `InputError` for an object that floats, sinks, or stands off its support."""
    floors = [o.bounds for o in objects if o.kind == "floor"]
    for o in objects:
        if o.kind in _STRUCTURE:
            continue
        (x0, y0, z0), (x1, y1, _) = o.bounds
        if o.support < 0:
            if abs(z0) > _REST_TOL:
                raise InputError(
                    f"objects: {o.name} (id {o.id}) has support -1 (the floor) but its lowest "
                    f"point is at z={z0:.3f} m; stand it on the floor (z = 0), or give the id "
                    "of the object it stands on as its support."
                )
            inside = [
                f
                for f in floors
                if x0 >= f[0, 0] - _OVERLAP_TOL
                and x1 <= f[1, 0] + _OVERLAP_TOL
                and y0 >= f[0, 1] - _OVERLAP_TOL
                and y1 <= f[1, 1] + _OVERLAP_TOL
            ]
            if floors and not inside:
                f = floors[0]
                raise InputError(
                    f"objects: {o.name} (id {o.id}) reaches off the floor: its footprint spans "
                    f"x [{x0:.3f}, {x1:.3f}], y [{y0:.3f}, {y1:.3f}] m, the floor x "
                    f"[{f[0, 0]:.3f}, {f[1, 0]:.3f}], y [{f[0, 1]:.3f}, {f[1, 1]:.3f}] m; move "
                    "it onto the floor."
                )
            continue
        base = by_id[o.support]
        cx, cy = (x0 + x1) / 2, (y0 + y1) / 2
        if not _on_part(cx, cy, z0, base):
            raise InputError(
                f"objects: {o.name} (id {o.id}) stands on {base.name} (id {base.id}), but its "
                f"bottom (centre ({cx:.3f}, {cy:.3f}), z={z0:.3f} m) is not on a top face of "
                f"{base.name}; place it on that object's top, or correct its support."
            )


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
    pose_arr = _floats("robot_pose", robot_pose)
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


# ---------------------------------------------------------------------------------- sampling

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
