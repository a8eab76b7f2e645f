"""Side-view world descriptions: ``worlds/sideview.yaml`` and ``worlds/sideview_scenes/``.

The side view is the world x-z plane: x horizontal, z up, the table surface at z = 0. Its
objects are cuboids from their own catalogue (``worlds/cuboids.yaml``, the format of
``worlds/objects.yaml``), read with `probaff.sim.specs.load_catalogue`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar

from probaff.errors import ConfigError
from probaff.sim import world_files as wf
from probaff.sim.pusher import HandSpec, HandWorldSpec, read_hand
from probaff.sim.specs import ArmSpec, ObjectSpec, load_arm_spec, load_catalogue
from probaff.sim.world_files import CheckedSpec, Range

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

SKILLS = ("pick", "place")
SCENES = "sideview_scenes"
"""Folder of the side view's scene templates, under `worlds_dir()`."""


@dataclass(frozen=True)
class SideGripperSpec(CheckedSpec):
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

    POSITIVE = (
        "span",
        "finger_size",
        "finger_mass",
        "hand_mass",
        "squeeze_force",
        "finger_speed",
        "max_force",
        "max_torque",
        "max_speed",
    )
    NONNEG = ("tip_below_tcp", "pad_friction")
    PAIRS: ClassVar[dict[str, str]] = {"finger_size": "(thickness, length)"}

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
        super().__post_init__()
        if self.tip_below_tcp >= self.finger_size[1]:
            raise ConfigError(
                f"SideGripperSpec.tip_below_tcp {self.tip_below_tcp} must be shorter than the "
                f"finger length {self.finger_size[1]}."
            )


@dataclass(frozen=True)
class SidePhysicsSpec(CheckedSpec):
    """Fixed-step integration settings of the side-view pymunk space.

    Attributes:
        gravity: Gravitational acceleration along -z (m/s^2).
        control_rate: Control ticks per second (Hz).
        substeps: Physics steps per control tick.
        iterations: pymunk solver iterations per step.
        collision_slop: Overlap pymunk allows between shapes (m).
        settle_time: Time the objects settle before the hand moves (s).
        record_rate: Samples per second of the recorded trajectories (Hz).
    """

    POSITIVE = ("gravity", "control_rate", "record_rate")
    NONNEG = ("collision_slop", "settle_time")
    COUNTS = ("substeps", "iterations")

    gravity: float
    control_rate: float
    substeps: int
    iterations: int
    collision_slop: float
    settle_time: float
    record_rate: float


@dataclass(frozen=True)
class PickSkillSpec(CheckedSpec):
    """Parameters of the pick skill (thesis chapter 6).

    Attributes:
        approach_height: The tcp starts this far above the object's top (m).
        grasp_fraction: The tcp goes down to this fraction of the object's height.
        close_time: How long the fingers close before the lift (s).
        lift: Lift height (m).
        hold_time: How long the object is held still after the lift (s).
    """

    POSITIVE = ("approach_height", "grasp_fraction", "close_time", "lift")
    NONNEG = ("hold_time",)

    approach_height: float
    grasp_fraction: float
    close_time: float
    lift: float
    hold_time: float

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.grasp_fraction > 1.0:
            raise ConfigError(
                f"PickSkillSpec.grasp_fraction must lie in (0, 1], got {self.grasp_fraction}."
            )


@dataclass(frozen=True)
class PlaceSkillSpec(CheckedSpec):
    """Parameters of the place skill (thesis chapter 6).

    Attributes:
        hold_height: The held cube's bottom starts this far above the target top (m).
        release_height: ``(low, high)`` range of the cube bottom's height above the target when
            the fingers open (m).
        open_time: How long the fingers open (s).
        settle_time: How long is simulated after the fingers open (s).
    """

    POSITIVE = ("hold_height", "open_time")
    NONNEG = ("release_height", "settle_time")

    hold_height: float
    release_height: Range
    open_time: float
    settle_time: float

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.release_height[1] > self.hold_height:
            raise ConfigError(
                f"PlaceSkillSpec.release_height {self.release_height} must not exceed "
                f"hold_height {self.hold_height}: the cube is lowered, never raised."
            )


@dataclass(frozen=True)
class SideViewSpec(CheckedSpec, HandWorldSpec):
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
        hand: How the palm follows the arm's command: stiff tracking or a Cartesian impedance
            that compensates the weight of the palm and fingers, not of a held object
            (``hand`` section; stiff when absent).
    """

    POSITIVE = ("table_length", "speed", "acceleration", "slip_tolerance", "place_tolerance")
    NONNEG = ("table_friction",)

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
    hand: HandSpec = field(default_factory=HandSpec)

    def __post_init__(self) -> None:
        super().__post_init__()
        if not math.isfinite(self.plane_y):
            raise ConfigError(f"SideViewSpec.plane_y must be finite, got {self.plane_y!r}.")
        self.check_hand(
            "side-view world",
            self.gripper.hand_mass,
            self.physics.control_rate,
            self.physics.substeps,
        )


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


_TABLE_KEYS = {"length": "table_length", "friction": "table_friction"}
"""The ``table`` section of ``worlds/sideview.yaml``: key -> `SideViewSpec` field."""
_SKILL_KEYS = ("speed", "acceleration", "slip_tolerance", "place_tolerance")
"""The `SideViewSpec` fields in the ``skills`` section of ``worlds/sideview.yaml``."""


def load_sideview(path: Path | None = None) -> SideViewSpec:
    """Load and validate the side-view world (``worlds/sideview.yaml``).

    Args:
        path: Another world file; defaults to the one in `worlds_dir()`.

    Raises:
        ConfigError: Naming the file and field of a missing, unknown or malformed entry.
    """
    raw, w, p = wf.load_root(path, "sideview.yaml")
    wf.no_extra(w, raw, {"catalogue", "table", "physics", "arm", "gripper", "skills", "hand"})
    table = wf.section(w, raw, "table", set(_TABLE_KEYS))
    phys = wf.section(w, raw, "physics", set(SidePhysicsSpec.__dataclass_fields__))
    arm = wf.section(w, raw, "arm", {"urdf", "tcp_link", "base_xyz", "base_yaw", "plane_y", "ik"})
    grip = wf.section(w, raw, "gripper", set(SideGripperSpec.__dataclass_fields__))
    skills = wf.section(w, raw, "skills", {*_SKILL_KEYS, "pick", "place"})
    s = f"{w}:skills"
    pick = wf.section(s, skills, "pick", set(PickSkillSpec.__dataclass_fields__))
    place = wf.section(s, skills, "place", set(PlaceSkillSpec.__dataclass_fields__))
    catalogue = p.parent / str(wf.take(w, raw, "catalogue"))
    if not catalogue.is_file():
        raise ConfigError(f"{w}:catalogue names {catalogue}, which does not exist.")
    return SideViewSpec(
        catalogue=catalogue,
        **SideViewSpec.read_fields(f"{w}:table", table, _TABLE_KEYS),
        physics=SidePhysicsSpec.read(f"{w}:physics", phys),
        arm=load_arm_spec(f"{w}:arm", arm, p.parent, push_height=0.0),
        plane_y=wf.number_field(f"{w}:arm", arm, "plane_y"),
        gripper=SideGripperSpec.read(f"{w}:gripper", grip),
        **SideViewSpec.read_fields(s, skills, {k: k for k in _SKILL_KEYS}),
        pick=PickSkillSpec.read(f"{s}.pick", pick),
        place=PlaceSkillSpec.read(f"{s}.place", place),
        hand=read_hand(f"{w}:hand", raw.get("hand")),
    )


def list_sideview_scenes() -> list[str]:
    """Names of the side-view scene templates in ``worlds/sideview_scenes/``."""
    return wf.scene_names(SCENES)


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
    e = wf.mapping(where, raw)
    wf.no_extra(where, e, {"choices", "x", "stacked_on", "probability"})
    choices = wf.take(where, e, "choices")
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
    probability = wf.number(f"{where}.probability", e.get("probability", 1.0), positive=True)
    if probability > 1.0:
        raise ConfigError(f"{where}.probability must lie in (0, 1], got {probability}.")
    return SideObjectPlacement(objs, wf.range_field(where, e, "x"), on, probability)


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
    path = wf.worlds_dir() / SCENES / f"{name}.yaml"
    if not path.is_file():
        raise ConfigError(
            f"unknown side-view scene {name!r}; available scenes: {list_sideview_scenes()}."
        )
    cat = catalogue if catalogue is not None else load_catalogue(load_sideview().catalogue)
    w = path.name
    raw = wf.mapping(w, wf.read_yaml(path))
    wf.no_extra(w, raw, {"name", "description", "skill", "objects", "gap", "held", "target"})
    skill = wf.take(w, raw, "skill")
    if skill not in SKILLS:
        raise ConfigError(f"{w}:skill must be one of {list(SKILLS)}, got {skill!r}.")
    objs_raw = raw.get("objects") or []
    if not isinstance(objs_raw, list):
        raise ConfigError(f"{w}:objects must be a list of placements.")
    placements = tuple(
        _side_placement(f"{w}:objects[{i}]", o, cat, i) for i, o in enumerate(objs_raw)
    )
    gap = wf.number(f"{w}:gap", raw.get("gap", 0.0), nonneg=True)
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
            **wf.scene_header(raw, name), skill=skill, objects=placements, gap=gap
        )
    if placements and placements[0].on is not None:
        raise ConfigError(f"{w}:objects[0] must rest on the table (no 'stacked_on').")
    held = _object(f"{w}:held", wf.take(w, raw, "held"), cat)
    target = wf.section(w, raw, "target", {"offset", "table_x"})
    return SideViewSceneSpec(
        **wf.scene_header(raw, name),
        skill=skill,
        objects=placements,
        gap=gap,
        held=held,
        target_offset=wf.range_field(f"{w}:target", target, "offset", (0.0, 0.0)),
        table_x=wf.range_field(f"{w}:target", target, "table_x"),
    )
