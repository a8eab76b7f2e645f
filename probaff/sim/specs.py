"""Specs that several worlds share: catalogue objects and the arm's mounting.

The tabletop and the side view both draw their objects from a catalogue file of the same format
(``worlds/objects.yaml``, ``worlds/cuboids.yaml``) and both mount the URDF arm
(``worlds/arm.urdf``) through an ``arm`` section of their world file.

Covered by tests/sim/test_sim_config.py.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cache
from pathlib import Path
from typing import Any

from probaff.errors import ConfigError
from probaff.sim import world_files as wf

__all__ = ["ArmSpec", "ObjectSpec", "load_arm_spec", "load_catalogue"]

_OBJECT_FIELDS = {"height", "mass", "ground_friction", "contact_friction"}


@dataclass(frozen=True)
class ObjectSpec:
    """One catalogue object.

    Attributes:
        name: Catalogue key.
        shape: ``"box"`` or ``"circle"``.
        size: ``(length, width)`` of a box footprint along its object x and y axes (m); for a
            circle ``(2 r, 2 r)``.
        radius: Circle radius (m); 0 for boxes.
        height: Height above the table (m).
        mass: Mass (kg).
        ground_friction: Coulomb coefficient against the table.
        contact_friction: Surface coefficient; a contact pair uses the geometric mean.
    """

    name: str
    shape: str
    size: tuple[float, float]
    radius: float
    height: float
    mass: float
    ground_friction: float
    contact_friction: float

    def __post_init__(self) -> None:
        if self.shape not in ("box", "circle"):
            raise ConfigError(
                f"ObjectSpec.shape of {self.name!r} must be 'box' or 'circle', got {self.shape!r}."
            )
        if not isinstance(self.size, (tuple, list)) or len(self.size) != 2:
            raise ConfigError(
                f"ObjectSpec.size of {self.name!r} must be a (length, width) pair, got "
                f"{self.size!r}."
            )
        wf.check_spec(
            self,
            positive=("size", "height", "mass"),
            nonneg=("ground_friction", "contact_friction"),
        )
        wf.check_spec(
            self,
            **({"positive": ("radius",)} if self.shape == "circle" else {"nonneg": ("radius",)}),
        )

    @property
    def bounding_radius(self) -> float:
        """Radius (m) of the smallest origin-centred circle that holds the footprint."""
        return self.radius if self.shape == "circle" else 0.5 * math.hypot(*self.size)


@dataclass(frozen=True)
class ArmSpec:
    """The arm's URDF and mounting. ``base_xyz``/``base_yaw`` give T_world_base."""

    urdf: Path
    tcp_link: str
    base_xyz: tuple[float, float, float]
    base_yaw: float
    push_height: float
    pos_tolerance: float
    rot_tolerance: float
    max_iterations: int
    waypoint_spacing: float


def load_arm_spec(
    where: str, arm: dict[str, Any], folder: Path, *, push_height: float | None = None
) -> ArmSpec:
    """The `ArmSpec` of a world file's ``arm`` section.

    Args:
        where: Name of the section, ``"FILE:arm"``.
        arm: The section: ``urdf`` (relative to `folder`), ``tcp_link``, ``base_xyz``,
            ``base_yaw``, ``ik`` (``pos_tolerance``, ``rot_tolerance``, ``max_iterations``,
            ``waypoint_spacing``) and, unless `push_height` is given, ``push_height``.
        folder: The world file's folder.
        push_height: The tool height of a push, for a world without one in its file.

    Raises:
        ConfigError: Naming the missing or malformed field.
    """
    ik = wf.section(where, arm, "ik")
    base = wf.take(where, arm, "base_xyz")
    if not isinstance(base, list) or len(base) != 3:
        raise ConfigError(f"{where}.base_xyz must be [x, y, z], got {base!r}.")
    ik_where = f"{where}.ik"
    return ArmSpec(
        urdf=folder / str(wf.take(where, arm, "urdf")),
        tcp_link=str(wf.take(where, arm, "tcp_link")),
        base_xyz=tuple(wf.number(f"{where}.base_xyz", b) for b in base),  # type: ignore[arg-type]
        base_yaw=wf.number_field(where, arm, "base_yaw"),
        push_height=(
            wf.number_field(where, arm, "push_height", nonneg=True)
            if push_height is None
            else push_height
        ),
        pos_tolerance=wf.number_field(ik_where, ik, "pos_tolerance", positive=True),
        rot_tolerance=wf.number_field(ik_where, ik, "rot_tolerance", positive=True),
        max_iterations=wf.count_field(ik_where, ik, "max_iterations"),
        waypoint_spacing=wf.number_field(ik_where, ik, "waypoint_spacing", positive=True),
    )


def _catalogue_object(where: str, name: str, e: dict[str, Any]) -> ObjectSpec:
    """One catalogue entry: a box (``size``) or a circle (``radius``)."""
    shape = wf.take(where, e, "shape")
    if shape == "box":
        wf.no_extra(where, e, {"shape", "size", *_OBJECT_FIELDS})
        size_raw = wf.take(where, e, "size")
        if not isinstance(size_raw, list) or len(size_raw) != 2:
            raise ConfigError(f"{where}.size must be [length, width], got {size_raw!r}.")
        size = (
            wf.number(f"{where}.size[0]", size_raw[0], positive=True),
            wf.number(f"{where}.size[1]", size_raw[1], positive=True),
        )
        radius = 0.0
    elif shape == "circle":
        wf.no_extra(where, e, {"shape", "radius", *_OBJECT_FIELDS})
        radius = wf.number_field(where, e, "radius", positive=True)
        size = (2 * radius, 2 * radius)
    else:
        raise ConfigError(f"{where}.shape must be 'box' or 'circle', got {shape!r}.")
    return ObjectSpec(
        name=name,
        shape=shape,
        size=size,
        radius=radius,
        height=wf.number_field(where, e, "height", positive=True),
        mass=wf.number_field(where, e, "mass", positive=True),
        ground_friction=wf.number_field(where, e, "ground_friction", nonneg=True),
        contact_friction=wf.number_field(where, e, "contact_friction", nonneg=True),
    )


@cache
def _catalogue_cached(path: str) -> dict[str, ObjectSpec]:
    p = Path(path)
    raw = wf.mapping(str(p), wf.read_yaml(p))
    out = {
        str(name): _catalogue_object(
            f"{p.name}:{name}", str(name), wf.mapping(f"{p.name}:{name}", e)
        )
        for name, e in raw.items()
    }
    if not out:
        raise ConfigError(f"{p} defines no objects.")
    return out


def load_catalogue(path: Path | None = None) -> dict[str, ObjectSpec]:
    """Load an object catalogue (``worlds/objects.yaml`` by default).

    Args:
        path: Another catalogue file (e.g. the side view's ``worlds/cuboids.yaml``); defaults
            to the one in `wf.worlds_dir()`.

    Returns:
        Mapping from object name to its spec.
    """
    return _catalogue_cached(str(path or wf.worlds_dir() / "objects.yaml"))
