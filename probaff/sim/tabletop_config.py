"""The top-down tabletop's world file (``worlds/tabletop.yaml``) and scene templates.

A scene template (``worlds/scenes/NAME.yaml``) places catalogue objects (`probaff.sim.specs`)
and randomises them and the push skill's start; `probaff.sim.sampling.sample_scene` draws
concrete scenes from it.

Covered by tests/sim/test_sim_config.py.
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
    "GripperSpec",
    "PhysicsSpec",
    "PlacementSpec",
    "PushSpec",
    "SceneSpec",
    "TabletopSpec",
    "WallSpec",
    "list_scenes",
    "load_scene",
    "load_tabletop",
]

SCENES = "scenes"
"""Folder of the tabletop's scene templates, under `probaff.sim.world_files.worlds_dir()`."""


@dataclass(frozen=True)
class GripperSpec(CheckedSpec):
    """The two-finger hand as the physics sees it (a force-limited, tracked rigid body).

    Attributes:
        finger_radius: Radius of the round fingertips (m).
        push_opening: Distance between the finger centres while pushing (m, at most 0.15).
        mass: Mass of the hand (kg).
        max_force: Force limit of the arm's tracking controller at the hand (N).
        max_torque: Its torque limit about the vertical (N m).
        max_speed: Fastest correction of a tracking error (m/s).
        contact_friction: Friction coefficient of the finger pads.
    """

    POSITIVE = ("finger_radius", "push_opening", "mass", "max_force", "max_torque", "max_speed")
    NONNEG = ("contact_friction",)

    finger_radius: float
    push_opening: float
    mass: float
    max_force: float
    max_torque: float
    max_speed: float
    contact_friction: float


@dataclass(frozen=True)
class PhysicsSpec(CheckedSpec):
    """Fixed-step integration settings of the pymunk space.

    Attributes:
        gravity: Gravitational acceleration (m/s^2), for the ground friction's normal loads.
        control_rate: Control ticks per second (Hz); the arm's trajectory is sampled at it.
        substeps: Physics steps per control tick.
        iterations: pymunk solver iterations per step.
        collision_slop: Overlap pymunk allows between shapes (m).
        friction_grid: Ground-friction support points per footprint axis.
        overlap_correction: Fraction of an overlap beyond `collision_slop` that pymunk
            removes per physics step. pymunk states its rate per second
            (``Space.collision_bias``, the fraction left after one second); its default,
            ``0.9 ** 60``, removes 10 % per step of a 60 Hz game but only 2.6 % per step of
            this world's 240 Hz, too slow to undo what the iterative solver leaves when the
            hand squeezes a light object against a wall: 4.4 mm deep in 4,400 random
            ``near_wall`` pushes (seed 0), 1.9 mm at 10 % per step and 2.2 mm at the
            world's 20 % (worst of 9,900 pushes over seeds 0, 5 and 11: 2.2 mm).
            `collision_bias` converts it.
    """

    POSITIVE = ("gravity", "control_rate")
    NONNEG = ("collision_slop",)
    COUNTS = ("substeps", "iterations", "friction_grid")
    PROBABILITIES = ("overlap_correction",)

    gravity: float
    control_rate: float
    substeps: int
    iterations: int
    collision_slop: float
    friction_grid: int
    overlap_correction: float

    @property
    def collision_bias(self) -> float:
        """The value of pymunk's ``Space.collision_bias``: the overlap left after one second."""
        return (1.0 - self.overlap_correction) ** (self.control_rate * self.substeps)


@dataclass(frozen=True)
class TabletopSpec(CheckedSpec, HandWorldSpec):
    """The whole top-down tabletop world (``worlds/tabletop.yaml``).

    Attributes:
        table_size: Extent of the table along world x and y, centred at the origin (m).
        arm: The arm's URDF and mounting.
        gripper: The hand.
        physics: Integration settings.
        push_speed: Cruising hand speed along z_p (m/s).
        push_acceleration: Acceleration and deceleration of the hand (m/s^2).
        settle_time: Time simulated after the hand stops (s).
        record_rate: Samples per second of the recorded trajectories (Hz).
        hand: How the hand follows the arm's command: stiff tracking or a Cartesian
            impedance (``hand`` section; stiff when absent).
    """

    POSITIVE = ("table_size", "push_speed", "push_acceleration", "record_rate")
    NONNEG = ("settle_time",)
    PAIRS: ClassVar[dict[str, str]] = {"table_size": "(length, width)"}

    table_size: tuple[float, float]
    arm: ArmSpec
    gripper: GripperSpec
    physics: PhysicsSpec
    push_speed: float
    push_acceleration: float
    settle_time: float
    record_rate: float
    hand: HandSpec = field(default_factory=HandSpec)

    def __post_init__(self) -> None:
        super().__post_init__()
        self.check_hand(
            "tabletop world", self.gripper.mass, self.physics.control_rate, self.physics.substeps
        )


@dataclass(frozen=True)
class PlacementSpec:
    """Randomisation ranges for one object of a scene.

    The first object is placed in the world frame (``x``, ``y``, ``yaw``); later ones either in
    the world frame too, or in the pushing frame of the pushed object (``along`` z_p and
    ``lateral`` along y_p from its centre, ``yaw`` relative to the push direction).
    """

    choices: tuple[str, ...]
    x: Range | None = None
    y: Range | None = None
    along: Range | None = None
    lateral: Range | None = None
    yaw: Range = (-math.pi, math.pi)

    @property
    def in_push_frame(self) -> bool:
        """Whether the object is placed relative to the push."""
        return self.along is not None


@dataclass(frozen=True)
class WallSpec:
    """A fixed wall segment placed in the pushing frame of the pushed object."""

    along: Range
    lateral: Range
    length: float
    angle: Range


@dataclass(frozen=True)
class PushSpec:
    """Randomisation ranges of the push skill's start pose."""

    target: int
    distance: float
    direction: Range
    lateral_offset: Range
    start_gap: Range


@dataclass(frozen=True)
class SceneSpec:
    """A scene template (``worlds/scenes/NAME.yaml``)."""

    name: str
    description: str
    objects: tuple[PlacementSpec, ...]
    walls: tuple[WallSpec, ...]
    push: PushSpec
    ground_friction_scale: Range
    contact_friction_scale: Range
    mass_scale: Range = field(default=(1.0, 1.0))
    support_load_variation: float = 0.0


_PUSH_KEYS = {
    "speed": "push_speed",
    "acceleration": "push_acceleration",
    "settle_time": "settle_time",
    "record_rate": "record_rate",
}
"""The ``push`` section of ``worlds/tabletop.yaml``: key -> `TabletopSpec` field."""


def load_tabletop(path: Path | None = None) -> TabletopSpec:
    """Load and validate the tabletop world (``worlds/tabletop.yaml``).

    Args:
        path: Another world file; defaults to the one in `probaff.sim.world_files.worlds_dir()`.

    Raises:
        ConfigError: Naming the file and field of a missing, unknown or malformed entry.
        InputError: Naming the field of a ``hand`` value that is not a positive finite
            number, an unknown hand mode, or a compliant hand too stiff for the physics step.
    """
    raw, w, p = wf.load_root(path, "tabletop.yaml")
    table, arm, grip, phys, push = (
        wf.section(w, raw, key) for key in ("table", "arm", "gripper", "physics", "push")
    )
    opening = wf.number_field(f"{w}:gripper", grip, "push_opening", positive=True)
    if opening > 0.15 + 1e-9:
        raise ConfigError(f"{w}:gripper.push_opening {opening} exceeds the 0.15 m finger span.")
    return TabletopSpec(
        table_size=wf.pair_field(f"{w}:table", table, "size"),
        arm=load_arm_spec(f"{w}:arm", arm, p.parent),
        gripper=GripperSpec.read(f"{w}:gripper", grip, push_opening=opening),
        physics=PhysicsSpec.read(f"{w}:physics", phys),
        **TabletopSpec.read_fields(f"{w}:push", push, _PUSH_KEYS),
        hand=read_hand(f"{w}:hand", raw.get("hand")),
    )


def list_scenes() -> list[str]:
    """Names of the scene templates in ``worlds/scenes/``."""
    return wf.scene_names(SCENES)


def _placement(
    where: str, raw: Any, catalogue: dict[str, ObjectSpec], first: bool
) -> PlacementSpec:
    e = wf.mapping(where, raw)
    wf.no_extra(where, e, {"choices", "x", "y", "along", "lateral", "yaw"})
    choices = wf.take(where, e, "choices")
    if not isinstance(choices, list) or not choices:
        raise ConfigError(f"{where}.choices must be a non-empty list of catalogue names.")
    for c in choices:
        if c not in catalogue:
            raise ConfigError(
                f"{where}: unknown object {c!r}; the catalogue has {sorted(catalogue)}."
            )
    yaw = wf.range_field(where, e, "yaw", (-math.pi, math.pi))
    world_frame = "x" in e or "y" in e
    push_frame = "along" in e or "lateral" in e
    if first and push_frame:
        raise ConfigError(f"{where}: the first object is placed by world x/y, not along/lateral.")
    if world_frame and push_frame:
        raise ConfigError(
            f"{where}: place a later object either by world x/y (and a world yaw) or by "
            "along/lateral in the push frame, not both."
        )
    if first or world_frame:
        return PlacementSpec(
            tuple(choices),
            x=wf.range_field(where, e, "x"),
            y=wf.range_field(where, e, "y"),
            yaw=yaw,
        )
    return PlacementSpec(
        tuple(choices),
        along=wf.range_field(where, e, "along"),
        lateral=wf.range_field(where, e, "lateral"),
        yaw=yaw,
    )


def _walls(w: str, raw: dict[str, Any]) -> tuple[WallSpec, ...]:
    walls = []
    for i, wr in enumerate(raw.get("walls") or []):
        ww = f"{w}:walls[{i}]"
        we = wf.mapping(ww, wr)
        wf.no_extra(ww, we, {"along", "lateral", "length", "angle"})
        walls.append(
            WallSpec(
                along=wf.range_field(ww, we, "along"),
                lateral=wf.range_field(ww, we, "lateral"),
                length=wf.number_field(ww, we, "length", positive=True),
                angle=wf.range_field(ww, we, "angle", (0.0, 0.0)),
            )
        )
    return tuple(walls)


def _push(w: str, raw: dict[str, Any]) -> PushSpec:
    pr = wf.section(
        w, raw, "push", {"target", "distance", "direction", "lateral_offset", "start_gap"}
    )
    where = f"{w}:push"
    target = wf.count(f"{where}.target", pr.get("target", 0), minimum=0)
    if target != 0:
        raise ConfigError(f"{w}:push.target must be 0 (the first object is the pushed one).")
    return PushSpec(
        target=target,
        distance=wf.number_field(where, pr, "distance", positive=True),
        direction=wf.range_field(where, pr, "direction"),
        lateral_offset=wf.range_field(where, pr, "lateral_offset", (0.0, 0.0)),
        start_gap=wf.range_field(where, pr, "start_gap", nonneg=True),
    )


def load_scene(name: str) -> SceneSpec:
    """Load a scene template by name.

    Args:
        name: A name from `list_scenes()`.

    Raises:
        ConfigError: For an unknown scene, an unknown object, or a malformed field.
    """
    path = wf.worlds_dir() / SCENES / f"{name}.yaml"
    if not path.is_file():
        raise ConfigError(f"unknown scene {name!r}; available scenes: {list_scenes()}.")
    catalogue = load_catalogue()
    raw = wf.mapping(path.name, wf.read_yaml(path))
    w = path.name
    wf.no_extra(w, raw, {"name", "description", "objects", "walls", "push", "randomise"})
    objs = wf.take(w, raw, "objects")
    if not isinstance(objs, list) or not objs:
        raise ConfigError(f"{w}: objects must be a non-empty list.")
    placements = tuple(
        _placement(f"{w}:objects[{i}]", o, catalogue, i == 0) for i, o in enumerate(objs)
    )
    walls = _walls(w, raw)
    push = _push(w, raw)
    rnd = wf.optional_section(
        w,
        raw,
        "randomise",
        {"ground_friction_scale", "contact_friction_scale", "mass_scale", "support_load_variation"},
    )
    r = f"{w}:randomise"
    variation = wf.number(
        f"{r}.support_load_variation", rnd.get("support_load_variation", 0.0), nonneg=True
    )
    if variation >= 1.0:
        raise ConfigError(f"{w}:randomise.support_load_variation must be < 1, got {variation}.")
    return SceneSpec(
        **wf.scene_header(raw, name),
        objects=placements,
        walls=walls,
        push=push,
        ground_friction_scale=wf.range_field(
            r, rnd, "ground_friction_scale", (1.0, 1.0), positive=True
        ),
        contact_friction_scale=wf.range_field(
            r, rnd, "contact_friction_scale", (1.0, 1.0), positive=True
        ),
        mass_scale=wf.range_field(r, rnd, "mass_scale", (1.0, 1.0), positive=True),
        support_load_variation=variation,
    )
