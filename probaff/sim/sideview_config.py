"""Side-view world descriptions: ``worlds/sideview.yaml`` and ``worlds/sideview_scenes/``.

The side view is the world x-z plane: x horizontal, z up, the table surface at z = 0. Its
objects are cuboids from their own catalogue (``worlds/cuboids.yaml``, the format of
``worlds/objects.yaml``), read with `probaff.sim.config.load_catalogue`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from probaff.errors import ConfigError
from probaff.sim.config import (
    ArmSpec,
    ObjectSpec,
    _check_spec,
    _count_field,
    _field,
    _load_root,
    _mapping,
    _no_extra,
    _number,
    _pair,
    _range,
    _read_yaml,
    _take,
    load_catalogue,
    worlds_dir,
)

__all__ = [
    "PickSkillSpec",
    "PlaceSkillSpec",
    "SideGripperSpec",
    "SideObjectPlacement",
    "SidePhysicsSpec",
    "SideViewSceneSpec",
    "SideViewSpec",
    "list_sideview_scenes",
    "load_sideview",
    "load_sideview_scene",
]

Range = tuple[float, float]
SKILLS = ("pick", "place")


@dataclass(frozen=True)
class SideGripperSpec:
    """The two-finger hand of the side view.

    Attributes:
        span: Largest gap between the finger pads (m): the widest graspable object.
        finger_size: ``(thickness, length)`` of a finger along the closing axis and tool z (m).
        tip_below_tcp: How far the fingertips reach beyond the tcp along tool z (m).
        finger_mass: Mass of each finger (kg).
        hand_mass: Mass of the palm that carries the fingers (kg).
        squeeze_force: Largest force each finger presses with (N).
        finger_speed: Fastest opening or closing speed of each finger (m/s).
        max_force: Force limit of the arm's tracking controller at the hand (N).
        max_torque: Its torque limit about the viewing axis (N m).
        max_speed: Fastest correction of a tracking error (m/s).
        pad_friction: Surface coefficient of the finger pads.
    """

    span: float
    finger_size: tuple[float, float]
    tip_below_tcp: float
    finger_mass: float
    hand_mass: float
    squeeze_force: float
    finger_speed: float
    max_force: float
    max_torque: float
    max_speed: float
    pad_friction: float

    def __post_init__(self) -> None:
        if not isinstance(self.finger_size, (tuple, list)) or len(self.finger_size) != 2:
            raise ConfigError(
                "SideGripperSpec.finger_size must be a (thickness, length) pair, got "
                f"{self.finger_size!r}."
            )
        _check_spec(
            self,
            positive=(
                "span",
                "finger_size",
                "finger_mass",
                "hand_mass",
                "squeeze_force",
                "finger_speed",
                "max_force",
                "max_torque",
                "max_speed",
            ),
            nonneg=("tip_below_tcp", "pad_friction"),
        )
        if self.tip_below_tcp >= self.finger_size[1]:
            raise ConfigError(
                f"SideGripperSpec.tip_below_tcp {self.tip_below_tcp} must be shorter than the "
                f"finger length {self.finger_size[1]}."
            )


@dataclass(frozen=True)
class SidePhysicsSpec:
    """Fixed-step integration settings of the side-view pymunk space."""

    gravity: float
    control_rate: float
    substeps: int
    iterations: int
    collision_slop: float
    settle_time: float
    record_rate: float

    def __post_init__(self) -> None:
        _check_spec(
            self,
            positive=("gravity", "control_rate", "record_rate"),
            nonneg=("collision_slop", "settle_time"),
            counts=("substeps", "iterations"),
        )


@dataclass(frozen=True)
class PickSkillSpec:
    """Parameters of the pick skill (thesis chapter 6).

    Attributes:
        approach_height: The tcp starts this far above the object's top (m).
        grasp_fraction: The tcp goes down to this fraction of the object's height.
        close_time: How long the fingers close before the lift (s).
        lift: Lift height (m).
        hold_time: How long the object is held still after the lift (s).
    """

    approach_height: float
    grasp_fraction: float
    close_time: float
    lift: float
    hold_time: float

    def __post_init__(self) -> None:
        _check_spec(
            self,
            positive=("approach_height", "grasp_fraction", "close_time", "lift"),
            nonneg=("hold_time",),
        )
        if self.grasp_fraction > 1.0:
            raise ConfigError(
                f"PickSkillSpec.grasp_fraction must lie in (0, 1], got {self.grasp_fraction}."
            )


@dataclass(frozen=True)
class PlaceSkillSpec:
    """Parameters of the place skill (thesis chapter 6).

    Attributes:
        hold_height: The held cube's bottom starts this far above the target top (m).
        release_height: ``(low, high)`` range of the cube bottom's height above the target when
            the fingers open (m).
        open_time: How long the fingers open (s).
        settle_time: How long is simulated after the fingers open (s).
    """

    hold_height: float
    release_height: Range
    open_time: float
    settle_time: float

    def __post_init__(self) -> None:
        _check_spec(
            self,
            positive=("hold_height", "open_time"),
            nonneg=("release_height", "settle_time"),
        )
        if self.release_height[1] > self.hold_height:
            raise ConfigError(
                f"PlaceSkillSpec.release_height {self.release_height} must not exceed "
                f"hold_height {self.hold_height}: the cube is lowered, never raised."
            )


@dataclass(frozen=True)
class SideViewSpec:
    """The whole side-view world (``worlds/sideview.yaml``).

    Attributes:
        catalogue: Path of the cuboid catalogue.
        table_length: Extent of the table along world x, centred at x = 0 (m).
        table_friction: Surface coefficient of the table top.
        physics: Integration settings.
        arm: URDF and mounting (``push_height`` is unused in this world).
        plane_y: World y of the simulated plane (m).
        gripper: The hand.
        speed: Cruising tcp speed of every straight move (m/s).
        acceleration: Acceleration and deceleration of those moves (m/s^2).
        slip_tolerance: Motion of a held object relative to the hand past which it slipped (m).
        place_tolerance: Height error within which a released object counts as placed (m).
        pick: Pick parameters.
        place: Place parameters.
    """

    catalogue: Path
    table_length: float
    table_friction: float
    physics: SidePhysicsSpec
    arm: ArmSpec
    plane_y: float
    gripper: SideGripperSpec
    speed: float
    acceleration: float
    slip_tolerance: float
    place_tolerance: float
    pick: PickSkillSpec
    place: PlaceSkillSpec

    def __post_init__(self) -> None:
        _check_spec(
            self,
            positive=(
                "table_length",
                "speed",
                "acceleration",
                "slip_tolerance",
                "place_tolerance",
            ),
            nonneg=("table_friction",),
        )
        if not math.isfinite(self.plane_y):
            raise ConfigError(f"SideViewSpec.plane_y must be finite, got {self.plane_y!r}.")


@dataclass(frozen=True)
class SideObjectPlacement:
    """Randomisation of one object of a side-view scene.

    Attributes:
        choices: Catalogue objects to draw from (uniformly).
        x: ``(low, high)`` world x of the centre of an object on the table, or, for an object
            stacked on another, the offset of its centre from the supporting object's (m).
        on: Index of the earlier object this one is stacked on (``stacked_on`` in the file), or
            ``None`` (on the table).
        probability: Chance that the object is part of a drawn scene.
    """

    choices: tuple[ObjectSpec, ...]
    x: Range
    on: int | None = None
    probability: float = 1.0


@dataclass(frozen=True)
class SideViewSceneSpec:
    """A side-view scene template (``worlds/sideview_scenes/NAME.yaml``).

    Attributes:
        name: Template name.
        description: One line on what it holds.
        skill: ``"pick"`` (the last drawn object is picked) or ``"place"``.
        objects: Placements of the objects resting in the scene, in order; an object is only
            stacked on an earlier one, so nothing rests on the last drawn one (place: the
            possible supports; the held object goes onto the last drawn one, or the table).
        gap: Least free space between neighbouring objects on the same support (m).
        held: Place: the held object.
        target_offset: Place: x of the held object's centre from its support's centre (m).
        table_x: Place: world x of the held object's centre when the target is the table (m).
    """

    name: str
    description: str
    skill: str
    objects: tuple[SideObjectPlacement, ...]
    gap: float = 0.0
    held: ObjectSpec | None = None
    target_offset: Range = (0.0, 0.0)
    table_x: Range = (0.0, 0.0)


def load_sideview(path: Path | None = None) -> SideViewSpec:
    """Load and validate the side-view world (``worlds/sideview.yaml``).

    Args:
        path: Another world file; defaults to the one in `worlds_dir()`.

    Raises:
        ConfigError: Naming the file and field of a missing, unknown or malformed entry.
    """
    raw, w, p = _load_root(path, "sideview.yaml")
    _no_extra(w, raw, {"catalogue", "table", "physics", "arm", "gripper", "skills"})
    table = _mapping(f"{w}:table", _take(w, raw, "table"))
    _no_extra(f"{w}:table", table, {"length", "friction"})
    phys = _mapping(f"{w}:physics", _take(w, raw, "physics"))
    _no_extra(
        f"{w}:physics",
        phys,
        {
            "gravity",
            "control_rate",
            "substeps",
            "iterations",
            "collision_slop",
            "settle_time",
            "record_rate",
        },
    )
    arm = _mapping(f"{w}:arm", _take(w, raw, "arm"))
    _no_extra(f"{w}:arm", arm, {"urdf", "tcp_link", "base_xyz", "base_yaw", "plane_y", "ik"})
    ik = _mapping(f"{w}:arm.ik", _take(f"{w}:arm", arm, "ik"))
    grip = _mapping(f"{w}:gripper", _take(w, raw, "gripper"))
    grip_keys = {f.name for f in SideGripperSpec.__dataclass_fields__.values()}
    _no_extra(f"{w}:gripper", grip, grip_keys)
    skills = _mapping(f"{w}:skills", _take(w, raw, "skills"))
    _no_extra(
        f"{w}:skills",
        skills,
        {"speed", "acceleration", "slip_tolerance", "place_tolerance", "pick", "place"},
    )
    pick = _mapping(f"{w}:skills.pick", _take(f"{w}:skills", skills, "pick"))
    _no_extra(f"{w}:skills.pick", pick, set(PickSkillSpec.__dataclass_fields__))
    place = _mapping(f"{w}:skills.place", _take(f"{w}:skills", skills, "place"))
    _no_extra(f"{w}:skills.place", place, set(PlaceSkillSpec.__dataclass_fields__))
    base = _take(f"{w}:arm", arm, "base_xyz")
    if not isinstance(base, list) or len(base) != 3:
        raise ConfigError(f"{w}:arm.base_xyz must be [x, y, z], got {base!r}.")
    catalogue = p.parent / str(_take(w, raw, "catalogue"))
    if not catalogue.is_file():
        raise ConfigError(f"{w}:catalogue names {catalogue}, which does not exist.")
    span = _field(w, "gripper", grip, "span", positive=True)
    return SideViewSpec(
        catalogue=catalogue,
        table_length=_field(w, "table", table, "length", positive=True),
        table_friction=_field(w, "table", table, "friction", nonneg=True),
        physics=SidePhysicsSpec(
            gravity=_field(w, "physics", phys, "gravity", positive=True),
            control_rate=_field(w, "physics", phys, "control_rate", positive=True),
            substeps=_count_field(w, "physics", phys, "substeps"),
            iterations=_count_field(w, "physics", phys, "iterations"),
            collision_slop=_field(w, "physics", phys, "collision_slop", nonneg=True),
            settle_time=_field(w, "physics", phys, "settle_time", nonneg=True),
            record_rate=_field(w, "physics", phys, "record_rate", positive=True),
        ),
        arm=ArmSpec(
            urdf=p.parent / str(_take(f"{w}:arm", arm, "urdf")),
            tcp_link=str(_take(f"{w}:arm", arm, "tcp_link")),
            base_xyz=tuple(_number(f"{w}:arm.base_xyz", b) for b in base),  # type: ignore[arg-type]
            base_yaw=_field(w, "arm", arm, "base_yaw"),
            push_height=0.0,
            pos_tolerance=_field(w, "arm.ik", ik, "pos_tolerance", positive=True),
            rot_tolerance=_field(w, "arm.ik", ik, "rot_tolerance", positive=True),
            max_iterations=_count_field(w, "arm.ik", ik, "max_iterations"),
            waypoint_spacing=_field(w, "arm.ik", ik, "waypoint_spacing", positive=True),
        ),
        plane_y=_field(w, "arm", arm, "plane_y"),
        gripper=SideGripperSpec(
            span=span,
            finger_size=_pair(
                f"{w}:gripper.finger_size", _take(f"{w}:gripper", grip, "finger_size")
            ),
            tip_below_tcp=_field(w, "gripper", grip, "tip_below_tcp", nonneg=True),
            finger_mass=_field(w, "gripper", grip, "finger_mass", positive=True),
            hand_mass=_field(w, "gripper", grip, "hand_mass", positive=True),
            squeeze_force=_field(w, "gripper", grip, "squeeze_force", positive=True),
            finger_speed=_field(w, "gripper", grip, "finger_speed", positive=True),
            max_force=_field(w, "gripper", grip, "max_force", positive=True),
            max_torque=_field(w, "gripper", grip, "max_torque", positive=True),
            max_speed=_field(w, "gripper", grip, "max_speed", positive=True),
            pad_friction=_field(w, "gripper", grip, "pad_friction", nonneg=True),
        ),
        speed=_field(w, "skills", skills, "speed", positive=True),
        acceleration=_field(w, "skills", skills, "acceleration", positive=True),
        slip_tolerance=_field(w, "skills", skills, "slip_tolerance", positive=True),
        place_tolerance=_field(w, "skills", skills, "place_tolerance", positive=True),
        pick=PickSkillSpec(
            approach_height=_field(w, "skills.pick", pick, "approach_height", positive=True),
            grasp_fraction=_field(w, "skills.pick", pick, "grasp_fraction", positive=True),
            close_time=_field(w, "skills.pick", pick, "close_time", positive=True),
            lift=_field(w, "skills.pick", pick, "lift", positive=True),
            hold_time=_field(w, "skills.pick", pick, "hold_time", nonneg=True),
        ),
        place=PlaceSkillSpec(
            hold_height=_field(w, "skills.place", place, "hold_height", positive=True),
            release_height=_range(
                f"{w}:skills.place.release_height",
                _take(f"{w}:skills.place", place, "release_height"),
                nonneg=True,
            ),
            open_time=_field(w, "skills.place", place, "open_time", positive=True),
            settle_time=_field(w, "skills.place", place, "settle_time", nonneg=True),
        ),
    )


def list_sideview_scenes() -> list[str]:
    """Names of the side-view scene templates in ``worlds/sideview_scenes/``."""
    return sorted(p.stem for p in (worlds_dir() / "sideview_scenes").glob("*.yaml"))


def _object(where: str, name: Any, catalogue: dict[str, ObjectSpec]) -> ObjectSpec:
    if not isinstance(name, str) or name not in catalogue:
        raise ConfigError(
            f"{where}: unknown object {name!r}; the catalogue has {sorted(catalogue)}."
        )
    obj = catalogue[name]
    if obj.shape != "box":
        raise ConfigError(f"{where}: {name!r} is a {obj.shape}; the side view holds boxes only.")
    return obj


def _side_placement(
    where: str, raw: Any, catalogue: dict[str, ObjectSpec], index: int
) -> SideObjectPlacement:
    e = _mapping(where, raw)
    _no_extra(where, e, {"choices", "x", "stacked_on", "probability"})
    choices = _take(where, e, "choices")
    if not isinstance(choices, list) or not choices:
        raise ConfigError(f"{where}.choices must be a non-empty list of catalogue names.")
    objs = tuple(_object(f"{where}.choices[{i}]", c, catalogue) for i, c in enumerate(choices))
    on_raw = e.get("stacked_on")
    on: int | None = None
    if on_raw is not None:
        if isinstance(on_raw, bool) or not isinstance(on_raw, int) or not 0 <= on_raw < index:
            raise ConfigError(
                f"{where}.stacked_on must be the index of an earlier object (0..{index - 1}), got "
                f"{on_raw!r}."
            )
        on = on_raw
    probability = _number(f"{where}.probability", e.get("probability", 1.0), positive=True)
    if probability > 1.0:
        raise ConfigError(f"{where}.probability must lie in (0, 1], got {probability}.")
    return SideObjectPlacement(objs, _range(f"{where}.x", _take(where, e, "x")), on, probability)


def load_sideview_scene(
    name: str, catalogue: dict[str, ObjectSpec] | None = None
) -> SideViewSceneSpec:
    """Load a side-view scene template by name.

    Args:
        name: A name from `list_sideview_scenes()`.
        catalogue: The cuboid catalogue; by default the one `load_sideview()` names.

    Raises:
        ConfigError: For an unknown scene, an unknown object, or a malformed field.
    """
    if not isinstance(name, str):
        raise ConfigError(f"scene name must be a string, got {name!r}.")
    path = worlds_dir() / "sideview_scenes" / f"{name}.yaml"
    if not path.is_file():
        raise ConfigError(
            f"unknown side-view scene {name!r}; available scenes: {list_sideview_scenes()}."
        )
    cat = catalogue if catalogue is not None else load_catalogue(load_sideview().catalogue)
    w = path.name
    raw = _mapping(w, _read_yaml(path))
    _no_extra(w, raw, {"name", "description", "skill", "objects", "gap", "held", "target"})
    skill = _take(w, raw, "skill")
    if skill not in SKILLS:
        raise ConfigError(f"{w}:skill must be one of {list(SKILLS)}, got {skill!r}.")
    objs_raw = raw.get("objects") or []
    if not isinstance(objs_raw, list):
        raise ConfigError(f"{w}:objects must be a list of placements.")
    placements = tuple(
        _side_placement(f"{w}:objects[{i}]", o, cat, i) for i, o in enumerate(objs_raw)
    )
    gap = _number(f"{w}:gap", raw.get("gap", 0.0), nonneg=True)
    if skill == "pick":
        if not placements or placements[0].probability < 1.0 or placements[0].on is not None:
            raise ConfigError(
                f"{w}:objects[0] of a pick scene must always be drawn (probability 1) and rest "
                "on the table."
            )
        for key in ("held", "target"):
            if key in raw:
                raise ConfigError(f"{w}:{key} belongs to place scenes only; remove it.")
        return SideViewSceneSpec(
            str(raw.get("name", name)), str(raw.get("description", "")), skill, placements, gap
        )
    if placements and placements[0].on is not None:
        raise ConfigError(f"{w}:objects[0] must rest on the table (no 'stacked_on').")
    held = _object(f"{w}:held", _take(w, raw, "held"), cat)
    target = _mapping(f"{w}:target", _take(w, raw, "target"))
    _no_extra(f"{w}:target", target, {"offset", "table_x"})
    return SideViewSceneSpec(
        name=str(raw.get("name", name)),
        description=str(raw.get("description", "")),
        skill=skill,
        objects=placements,
        gap=gap,
        held=held,
        target_offset=_range(f"{w}:target.offset", target.get("offset", [0.0, 0.0])),
        table_x=_range(f"{w}:target.table_x", _take(f"{w}:target", target, "table_x")),
    )
