"""The office world's file (``worlds/office.yaml``): room, robot, furniture ranges and rules.

Covered by tests/sim/test_office.py.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from probaff._checks import check_finite
from probaff.errors import ConfigError, InputError
from probaff.sim import world_files as wf
from probaff.sim.world_files import CheckedSpec, Range

__all__ = [
    "WALLS",
    "OfficeBoxClass",
    "OfficeBoxesSpec",
    "OfficeChairSpec",
    "OfficeLabelRules",
    "OfficePlacementSpec",
    "OfficeRobotSpec",
    "OfficeRoomSpec",
    "OfficeSpec",
    "OfficeTableSpec",
    "load_office",
]

WALLS = ("+x", "-x", "+y", "-y")
"""The sides of the room that may hold a wall, in world axes."""


@dataclass(frozen=True)
class OfficeRoomSpec(CheckedSpec):
    """The room: floor extent, walls and floor slab (world frame, m).

    Attributes:
        x: ``(low, high)`` extent of the floor along world x.
        y: ``(low, high)`` extent of the floor along world y.
        wall_height: Height of the walls.
        wall_thickness: Thickness of the walls, which stand just outside the floor.
        floor_thickness: Thickness of the floor slab below z = 0.
        walls: The sides that hold a wall, from `WALLS`.
    """

    POSITIVE = ("wall_height", "wall_thickness", "floor_thickness")

    x: Range
    y: Range
    wall_height: float
    wall_thickness: float
    floor_thickness: float
    walls: tuple[str, ...]

    def __post_init__(self) -> None:
        super().__post_init__()
        for name in ("x", "y"):
            lo, hi = getattr(self, name)
            if not (math.isfinite(lo) and math.isfinite(hi) and hi > lo):
                raise ConfigError(
                    f"OfficeRoomSpec.{name} must be a finite [low, high], low < high."
                )
        for w in self.walls:
            if w not in WALLS:
                raise ConfigError(f"OfficeRoomSpec.walls: unknown side {w!r}; use {list(WALLS)}.")
        if len(set(self.walls)) != len(self.walls):
            raise ConfigError("OfficeRoomSpec.walls lists a side twice; name each side once.")


@dataclass(frozen=True)
class OfficeRobotSpec(CheckedSpec):
    """Where the robot stands.

    Attributes:
        x: World x of the robot (m).
        y: World y of the robot (m).
        yaw: The robot's heading in the world (rad); it looks along its own +x.
        keep_out: Radius round the robot kept free of objects (m).
    """

    NONNEG = ("keep_out",)

    x: float
    y: float
    yaw: float
    keep_out: float

    def __post_init__(self) -> None:
        try:
            check_finite("OfficeRobotSpec pose", [self.x, self.y, self.yaw])
        except InputError as exc:
            raise ConfigError(str(exc)) from None
        super().__post_init__()


class _CountedSpec(CheckedSpec):
    """A spec whose ``count`` is a ``(low, high)`` pair of integers, 0 <= low <= high."""

    count: tuple[int, int]

    def __post_init__(self) -> None:
        where = f"{type(self).__name__}.count"
        if not isinstance(self.count, tuple) or len(self.count) != 2:
            raise ConfigError(f"{where} must be a (low, high) pair of counts, got {self.count!r}.")
        lo, hi = (wf.count(f"{where}[{i}]", v, minimum=0) for i, v in enumerate(self.count))
        if lo > hi:
            raise ConfigError(f"{where} has low {lo} > high {hi}; swap them.")
        super().__post_init__()


@dataclass(frozen=True)
class OfficeTableSpec(_CountedSpec):
    """Ranges of the tables' count, sizes (m) and masses (kg); see ``worlds/office.yaml``.

    Attributes:
        count: ``(low, high)`` number of tables.
        top_length: Length of the top along the table's own x.
        top_depth: Depth of the top along its own y.
        top_thickness: Thickness of the top.
        height: Height of the top surface above the floor.
        leg_size: Side of a square leg.
        leg_inset: Distance from the top's edge to a leg's outer face.
        pedestal_probability: Share of tables on one central cylinder instead of four legs.
        pedestal_radius: Radius of that cylinder.
        mass: Mass of a table.
    """

    POSITIVE = (
        "top_length",
        "top_depth",
        "top_thickness",
        "height",
        "leg_size",
        "pedestal_radius",
        "mass",
    )
    NONNEG = ("leg_inset",)
    PROBABILITIES = ("pedestal_probability",)

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


@dataclass(frozen=True)
class OfficeChairSpec(_CountedSpec):
    """Ranges of the chairs (m, kg); a chair faces its own +x, its back at its -x edge.

    Attributes:
        count: ``(low, high)`` number of chairs.
        seat_width: Width of the seat across the chair (its own y).
        seat_depth: Depth of the seat, front to back (its own x).
        seat_height: Height of the seat's top surface above the floor.
        seat_thickness: Thickness of the seat.
        back_height: Height of the top of the back above the floor.
        back_thickness: Thickness of the back.
        leg_size: Side of a square leg or diameter of a round one.
        cylinder_leg_probability: Share of chairs with round legs.
        mass: Mass of a chair.
    """

    POSITIVE = (
        "seat_width",
        "seat_depth",
        "seat_height",
        "seat_thickness",
        "back_height",
        "back_thickness",
        "leg_size",
        "mass",
    )
    PROBABILITIES = ("cylinder_leg_probability",)

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


@dataclass(frozen=True)
class OfficeBoxClass(CheckedSpec):
    """One size class of boxes: a relative `weight` and ranges of extents (m) and mass (kg)."""

    POSITIVE = ("weight", "length", "width", "height", "mass")

    name: str
    weight: float
    length: Range
    width: Range
    height: Range
    mass: Range


@dataclass(frozen=True)
class OfficeBoxesSpec(_CountedSpec):
    """How many boxes, where they stand and their size classes.

    Attributes:
        count: Fewest and most boxes, ``(low, high)``.
        on_table_probability: Chance that a box is meant for a table top.
        on_box_probability: Chance that a box is meant for the top of a floor box.
        classes: The size classes, drawn by their weights.
    """

    PROBABILITIES = ("on_table_probability", "on_box_probability")

    count: tuple[int, int]
    on_table_probability: float
    on_box_probability: float
    classes: tuple[OfficeBoxClass, ...]

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.on_table_probability + self.on_box_probability > 1.0 + 1e-12:
            raise ConfigError(
                "OfficeBoxesSpec: on_table_probability + on_box_probability must be <= 1."
            )
        if not self.classes:
            raise ConfigError("OfficeBoxesSpec.classes is empty; give at least one box class.")


@dataclass(frozen=True)
class OfficePlacementSpec(CheckedSpec):
    """Rejection-sampling rules for placing objects (see `probaff.sim.office`).

    Attributes:
        min_clearance: Least gap between footprints of different objects and to the walls (m).
        against_wall_probability: Chance that a floor object is put against a wall.
        next_to_probability: Chance that a floor object is put next to an earlier one.
        near_gap: ``(low, high)`` gap of an object put against a wall or next to another (m).
        max_tries: Rejection-sampling tries per object.
    """

    POSITIVE = ("min_clearance", "near_gap")
    PROBABILITIES = ("against_wall_probability", "next_to_probability")
    COUNTS = ("max_tries",)

    min_clearance: float
    against_wall_probability: float
    next_to_probability: float
    near_gap: Range
    max_tries: int

    def __post_init__(self) -> None:
        super().__post_init__()
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
class OfficeLabelRules(CheckedSpec):
    """Thresholds of the label rules; `probaff.sim.office_labels` gives each one's source.

    Attributes:
        gripper_span: Widest part the fingers close across (m).
        push_clearance: A neighbour closer than this on a side blocks a push that way (m).
        max_lift_mass: Heaviest liftable object (kg).
        max_lift_size: Largest horizontal extent of a liftable object (m).
    """

    POSITIVE = ("gripper_span", "push_clearance", "max_lift_mass", "max_lift_size")

    gripper_span: float = 0.15
    push_clearance: float = 0.15
    max_lift_mass: float = 1.8
    max_lift_size: float = 0.6


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


def _fields(cls: type) -> set[str]:
    """The field names of the spec dataclass `cls`: the keys of its section."""
    return set(cls.__dataclass_fields__)  # type: ignore[attr-defined]


def _load_tables(w: str, raw: dict[str, Any]) -> OfficeTableSpec:
    s = f"{w}:tables"
    spec = OfficeTableSpec.read(s, wf.section(w, raw, "tables", _fields(OfficeTableSpec)))
    if spec.top_thickness[1] >= spec.height[0]:
        raise ConfigError(f"{s}.top_thickness must stay below the smallest height.")
    if 2 * (spec.leg_inset + spec.leg_size[1]) >= min(spec.top_length[0], spec.top_depth[0]):
        raise ConfigError(f"{s}: legs and inset do not fit under the smallest top; shrink them.")
    if 2 * spec.pedestal_radius[1] >= min(spec.top_length[0], spec.top_depth[0]):
        raise ConfigError(f"{s}.pedestal_radius is too large for the smallest top; shrink it.")
    return spec


def _load_chairs(w: str, raw: dict[str, Any]) -> OfficeChairSpec:
    s = f"{w}:chairs"
    spec = OfficeChairSpec.read(s, wf.section(w, raw, "chairs", _fields(OfficeChairSpec)))
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
    b = wf.section(w, raw, "boxes", _fields(OfficeBoxesSpec))
    classes_raw = wf.take(s, b, "classes")
    if not isinstance(classes_raw, list) or not classes_raw:
        raise ConfigError(f"{s}.classes must be a non-empty list of box classes.")
    classes = []
    for i, cr in enumerate(classes_raw):
        cw = f"{s}.classes[{i}]"
        c = wf.mapping(cw, cr)
        wf.no_extra(cw, c, _fields(OfficeBoxClass))
        classes.append(OfficeBoxClass.read(cw, c))
    p_table = wf.probability(f"{s}.on_table_probability", wf.take(s, b, "on_table_probability"))
    p_box = wf.probability(f"{s}.on_box_probability", wf.take(s, b, "on_box_probability"))
    if p_table + p_box > 1.0:
        raise ConfigError(f"{s}: on_table_probability + on_box_probability must be <= 1.")
    return OfficeBoxesSpec.read(
        s, b, on_table_probability=p_table, on_box_probability=p_box, classes=tuple(classes)
    )


def _load_room(w: str, raw: dict[str, Any]) -> OfficeRoomSpec:
    r = f"{w}:room"
    rr = wf.section(w, raw, "room", _fields(OfficeRoomSpec))
    walls = wf.take(r, rr, "walls")
    if not isinstance(walls, list) or not all(isinstance(v, str) for v in walls):
        raise ConfigError(f"{w}:room.walls must be a list of sides from {list(WALLS)}.")
    x, y = (wf.range_field(r, rr, k) for k in ("x", "y"))
    if x[1] <= x[0] or y[1] <= y[0]:
        raise ConfigError(f"{w}:room.x and room.y must each have low < high.")
    bad = [v for v in walls if v not in WALLS]
    if bad:
        raise ConfigError(f"{w}:room.walls: unknown side(s) {bad}; use {list(WALLS)}.")
    return OfficeRoomSpec.read(r, rr, x=x, y=y, walls=tuple(walls))


def _load_robot(w: str, raw: dict[str, Any]) -> OfficeRobotSpec:
    ro = wf.section(w, raw, "robot", {"pose", "keep_out"})
    pose = wf.take(f"{w}:robot", ro, "pose")
    if not isinstance(pose, list) or len(pose) != 3:
        raise ConfigError(f"{w}:robot.pose must be [x, y, yaw_deg], got {pose!r}.")
    px, py, pyaw = (wf.number(f"{w}:robot.pose[{i}]", v) for i, v in enumerate(pose))
    return OfficeRobotSpec(
        x=px,
        y=py,
        yaw=math.radians(pyaw),
        keep_out=wf.number_field(f"{w}:robot", ro, "keep_out", nonneg=True),
    )


def load_office(path: Path | None = None) -> OfficeSpec:
    """Load and validate the office world (``worlds/office.yaml``).

    Args:
        path: Another office file; defaults to the one in `probaff.sim.world_files.worlds_dir()`.

    Raises:
        ConfigError: For a missing file, malformed YAML, or a missing, unknown or out-of-range
            field, naming the file and the field.
    """
    raw, w, _ = wf.load_root(path, "office.yaml")
    wf.no_extra(w, raw, {"room", "robot", "tables", "chairs", "boxes", "placement", "labels"})
    room = _load_room(w, raw)
    robot = _load_robot(w, raw)
    pl = wf.section(w, raw, "placement", _fields(OfficePlacementSpec))
    lr = wf.section(w, raw, "labels", _fields(OfficeLabelRules))
    return OfficeSpec(
        room=room,
        robot=robot,
        tables=_load_tables(w, raw),
        chairs=_load_chairs(w, raw),
        boxes=_load_boxes(w, raw),
        placement=OfficePlacementSpec.read(f"{w}:placement", pl),
        labels=OfficeLabelRules.read(f"{w}:labels", lr),
    )
