"""Declarative world descriptions: locating and validating `worlds/` (URDF and YAML).

The world files live in the repository's top-level ``worlds/`` folder (or the folder named by the
``PROBAFF_WORLDS`` environment variable). This module turns them into frozen dataclasses and
rejects malformed or unknown entries with an error that names the file and the field.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from functools import cache
from pathlib import Path
from typing import TYPE_CHECKING, Any

import yaml

from probaff._checks import check_count, check_positive
from probaff.errors import ConfigError, InputError

if TYPE_CHECKING:
    from probaff.sim.camera import CameraSpec

__all__ = [
    "SENSOR_KINDS",
    "ArmSpec",
    "GripperSpec",
    "ObjectSpec",
    "PhysicsSpec",
    "PlacementSpec",
    "PushSpec",
    "SceneSpec",
    "TabletopSpec",
    "WallSpec",
    "WarehouseSpec",
    "list_scenes",
    "load_catalogue",
    "load_scene",
    "load_tabletop",
    "load_warehouse",
    "worlds_dir",
]

Range = tuple[float, float]


def worlds_dir() -> Path:
    """Return the folder that holds the world descriptions.

    ``$PROBAFF_WORLDS`` wins; otherwise the ``worlds/`` folder beside the ``probaff`` package
    (the repository checkout, for an editable install).

    Raises:
        ConfigError: If no such folder exists.
    """
    env = os.environ.get("PROBAFF_WORLDS")
    path = Path(env) if env else Path(__file__).resolve().parents[2] / "worlds"
    if not (path / "tabletop.yaml").is_file():
        raise ConfigError(
            f"no world descriptions found in {path}; install probaff from its repository with "
            "`pip install -e .` or set PROBAFF_WORLDS to the folder holding tabletop.yaml."
        )
    return path


def _read_yaml(path: Path) -> Any:
    """The parsed content of a world file.

    Raises:
        ConfigError: If `path` is missing, a folder, unreadable, not UTF-8 text or not YAML.
    """
    if path.is_dir():
        raise ConfigError(
            f"world file {path} is a folder, not a YAML file; give the path of a world file."
        )
    if not path.is_file():
        raise ConfigError(
            f"world file {path} does not exist; give the path of an existing world file."
        )
    try:
        return yaml.safe_load(path.read_text(encoding="utf-8"))
    except OSError as exc:
        raise ConfigError(
            f"cannot read world file {path} ({exc.strerror or exc}); check that you may read it."
        ) from exc
    except UnicodeDecodeError as exc:
        raise ConfigError(
            f"world file {path} is not UTF-8 text ({exc.reason} at byte {exc.start}); give the "
            "path of a YAML world file."
        ) from exc
    except yaml.YAMLError as exc:
        raise ConfigError(f"{path} is not valid YAML: {exc}; fix the file's syntax.") from exc


def _mapping(where: str, value: Any) -> dict[str, Any]:
    if not isinstance(value, dict):
        raise ConfigError(f"{where} must be a mapping, got {type(value).__name__}.")
    return value


def _number(where: str, value: Any, *, positive: bool = False, nonneg: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ConfigError(f"{where} must be a number, got {value!r}.")
    v = float(value)
    if not math.isfinite(v):
        raise ConfigError(f"{where} must be finite, got {value!r}.")
    if positive and v <= 0:
        raise ConfigError(f"{where} must be > 0, got {value!r}.")
    if nonneg and v < 0:
        raise ConfigError(f"{where} must be >= 0, got {value!r}.")
    return v


def _count(where: str, value: Any, *, minimum: int = 1) -> int:
    """`check_count` for a world file's field: the same rule, reported as a `ConfigError`."""
    try:
        return check_count(where, value, minimum=minimum)
    except InputError as exc:
        raise ConfigError(str(exc)) from None


def _check_spec(
    spec: object,
    *,
    positive: tuple[str, ...] = (),
    nonneg: tuple[str, ...] = (),
    counts: tuple[str, ...] = (),
) -> None:
    """Check the physical fields of a spec built in code, before any reaches pymunk.

    The loaders check the world files field by field; this repeats the range checks for a spec
    made or changed directly (e.g. with `dataclasses.replace`), where a negative mass or
    friction would otherwise abort the process inside Chipmunk.

    Args:
        spec: The dataclass instance.
        positive: Fields that must be finite numbers > 0 (a pair or tuple: each entry).
        nonneg: Fields that must be finite numbers >= 0.
        counts: Fields that must be positive integers.

    Raises:
        ConfigError: Naming the first bad field, e.g. ``ObjectSpec.mass``.
    """
    kind = type(spec).__name__
    try:
        for names, allow_zero in ((positive, False), (nonneg, True)):
            for name in names:
                value = getattr(spec, name)
                items = enumerate(value) if isinstance(value, (tuple, list)) else [(None, value)]
                for i, v in items:
                    where = f"{kind}.{name}" if i is None else f"{kind}.{name}[{i}]"
                    if isinstance(v, (bool, str, bytes)):
                        raise ConfigError(f"{where} must be a number, got {v!r}.")
                    check_positive(where, v, allow_zero=allow_zero)
        for name in counts:
            check_count(f"{kind}.{name}", getattr(spec, name))
    except InputError as exc:
        raise ConfigError(str(exc)) from None


def _count_field(w: str, where: str, table: dict[str, Any], key: str, *, minimum: int = 1) -> int:
    """The count ``table[key]`` of section `where` of file `w`, validated by `_count`."""
    return _count(f"{w}:{where}.{key}", _take(f"{w}:{where}", table, key), minimum=minimum)


def _range(where: str, value: Any, *, nonneg: bool = False, positive: bool = False) -> Range:
    if not isinstance(value, (list, tuple)) or len(value) != 2:
        raise ConfigError(f"{where} must be a [low, high] pair, got {value!r}.")
    lo = _number(f"{where}[0]", value[0], nonneg=nonneg, positive=positive)
    hi = _number(f"{where}[1]", value[1], nonneg=nonneg, positive=positive)
    if lo > hi:
        raise ConfigError(f"{where} has low {lo} > high {hi}; swap them.")
    return (lo, hi)


def _pair(where: str, value: Any) -> tuple[float, float]:
    if not isinstance(value, (list, tuple)) or len(value) != 2:
        raise ConfigError(f"{where} must be a pair of positive numbers, got {value!r}.")
    return (
        _number(f"{where}[0]", value[0], positive=True),
        _number(f"{where}[1]", value[1], positive=True),
    )


def _take(where: str, raw: dict[str, Any], key: str) -> Any:
    if key not in raw:
        raise ConfigError(f"{where} is missing the field '{key}'.")
    return raw[key]


def _field(w: str, where: str, table: dict[str, Any], key: str, **kw: bool) -> float:
    """The number ``table[key]`` of section `where` of file `w`, validated by `_number`."""
    return _number(f"{w}:{where}.{key}", _take(f"{w}:{where}", table, key), **kw)


def _no_extra(where: str, raw: dict[str, Any], allowed: set[str]) -> None:
    extra = set(raw) - allowed
    if extra:
        raise ConfigError(
            f"{where} has unknown field(s) {sorted(extra)}; allowed: {sorted(allowed)}."
        )


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
        _check_spec(
            self,
            positive=("size", "height", "mass"),
            nonneg=("ground_friction", "contact_friction"),
        )
        _check_spec(
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


@dataclass(frozen=True)
class GripperSpec:
    """The two-finger hand as the physics sees it (a force-limited, tracked rigid body)."""

    finger_radius: float
    push_opening: float
    mass: float
    max_force: float
    max_torque: float
    max_speed: float
    contact_friction: float

    def __post_init__(self) -> None:
        _check_spec(
            self,
            positive=(
                "finger_radius",
                "push_opening",
                "mass",
                "max_force",
                "max_torque",
                "max_speed",
            ),
            nonneg=("contact_friction",),
        )


@dataclass(frozen=True)
class PhysicsSpec:
    """Fixed-step integration settings of the pymunk space."""

    gravity: float
    control_rate: float
    substeps: int
    iterations: int
    collision_slop: float
    friction_grid: int

    def __post_init__(self) -> None:
        _check_spec(
            self,
            positive=("gravity", "control_rate"),
            nonneg=("collision_slop",),
            counts=("substeps", "iterations", "friction_grid"),
        )


@dataclass(frozen=True)
class TabletopSpec:
    """The whole top-down tabletop world (``worlds/tabletop.yaml``)."""

    table_size: tuple[float, float]
    arm: ArmSpec
    gripper: GripperSpec
    physics: PhysicsSpec
    push_speed: float
    push_acceleration: float
    settle_time: float
    record_rate: float

    def __post_init__(self) -> None:
        if not isinstance(self.table_size, (tuple, list)) or len(self.table_size) != 2:
            raise ConfigError(
                f"TabletopSpec.table_size must be a (length, width) pair, got {self.table_size!r}."
            )
        _check_spec(
            self,
            positive=("table_size", "push_speed", "push_acceleration", "record_rate"),
            nonneg=("settle_time",),
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


SENSOR_KINDS: tuple[str, ...] = ("camera", "scanner")
"""The warehouse robot's depth sensors: the head's depth camera (`probaff.sim.camera`), panned
round, or an idealised range scanner (Gaussian range noise only, 360 degrees)."""


@dataclass(frozen=True)
class WarehouseSpec:
    """The grid warehouse (``worlds/warehouse.yaml``); see that file for the fields' meaning.

    The ``sensor_*`` range fields describe the idealised scanner; with ``sensor_kind ==
    "camera"`` the robot's sensor is `camera` (a `probaff.sim.camera.CameraSpec`) at
    ``sensor_height``, panned to ``camera_pans`` azimuths over 360 degrees and tilted down by
    ``camera_tilt_deg``; its returns below ``floor_band`` (m) count as floor.
    """

    rows: int
    cols: int
    cell_size: float
    boxes: tuple[int, int]
    box_size: float
    box_height: float
    box_mass: float
    box_ground_friction: float
    box_contact_friction: float
    wall_height: float
    wall_thickness: float
    robot_radius: float
    robot_max_force: float
    robot_speed: float
    robot_acceleration: float
    sensor_height: float
    sensor_range: float
    sensor_azimuths: int
    sensor_elevations: tuple[float, ...]
    sensor_noise: float
    control_rate: float
    substeps: int
    iterations: int
    friction_grid: int
    collision_slop: float
    sensor_kind: str = "scanner"
    camera: CameraSpec | None = None
    camera_pans: int = 8
    camera_tilt_deg: float = 10.0
    floor_band: float = 0.15

    def __post_init__(self) -> None:
        if self.sensor_kind not in SENSOR_KINDS:
            raise ConfigError(
                f"WarehouseSpec.sensor_kind must be one of {', '.join(SENSOR_KINDS)}, got "
                f"{self.sensor_kind!r}."
            )
        if self.sensor_kind == "camera":
            from probaff.sim.camera import CameraSpec

            if not isinstance(self.camera, CameraSpec):
                raise ConfigError(
                    "WarehouseSpec.camera must be a CameraSpec (see load_camera) when "
                    f"sensor_kind is 'camera', got {type(self.camera).__name__}."
                )
        tilt = self.camera_tilt_deg
        if isinstance(tilt, (bool, str, bytes)) or not isinstance(tilt, (int, float)):
            raise ConfigError(
                f"WarehouseSpec.camera_tilt_deg must be a number of degrees, got {tilt!r}."
            )
        elevations = self.sensor_elevations
        if (
            not isinstance(elevations, (tuple, list))
            or not elevations
            or any(
                isinstance(e, (bool, str, bytes))
                or not isinstance(e, (int, float))
                or not -90.0 <= e <= 90.0
                for e in elevations
            )
        ):
            raise ConfigError(
                "WarehouseSpec.sensor_elevations must be a non-empty tuple of angles in "
                f"[-90, 90] degrees, got {elevations!r}."
            )
        if not (math.isfinite(self.camera_tilt_deg) and abs(self.camera_tilt_deg) < 90.0):
            raise ConfigError(
                f"WarehouseSpec.camera_tilt_deg must lie in (-90, 90) degrees, got "
                f"{self.camera_tilt_deg!r}."
            )
        _check_spec(
            self,
            positive=(
                "floor_band",
                "cell_size",
                "box_size",
                "box_height",
                "box_mass",
                "box_ground_friction",
                "wall_height",
                "wall_thickness",
                "robot_radius",
                "robot_max_force",
                "robot_speed",
                "robot_acceleration",
                "sensor_height",
                "sensor_range",
                "control_rate",
            ),
            nonneg=("box_contact_friction", "sensor_noise", "collision_slop"),
            counts=("sensor_azimuths", "substeps", "iterations", "friction_grid", "camera_pans"),
        )
        if self.sensor_kind == "camera":
            self._check_camera_view()

    def _check_camera_view(self) -> None:
        """Raise `ConfigError` unless the head camera images floor within its depth range."""
        cam = self.camera
        assert cam is not None  # checked with sensor_kind
        heights = cam.floor_heights(self.camera_tilt_deg)
        if heights is None:
            raise ConfigError(
                f"WarehouseSpec.camera_tilt_deg {self.camera_tilt_deg:g} points the camera "
                f"wholly above the floor; use a tilt above {cam.floor_tilt_deg:.1f} degrees "
                "(positive tilts look down)."
            )
        lo, hi = heights
        if not lo <= self.sensor_height <= hi:
            raise ConfigError(
                f"WarehouseSpec.sensor_height {self.sensor_height:g} m leaves the camera (range "
                f"{cam.min_range:g}-{cam.max_range:g} m) unable to image the floor at "
                f"camera_tilt_deg {self.camera_tilt_deg:g}; sensor_height must lie in "
                f"[{lo:.3f}, {hi:.3f}] m."
            )


def _load_root(path: Path | None, default: str) -> tuple[dict[str, Any], str, Path]:
    """``(mapping, file name for messages, path)`` of a world file."""
    p = path or worlds_dir() / default
    return _mapping(str(p), _read_yaml(p)), p.name, p


def load_warehouse(path: Path | None = None) -> WarehouseSpec:
    """Load and validate the warehouse world (``worlds/warehouse.yaml``).

    Args:
        path: Another warehouse file; defaults to the one in `worlds_dir()`.
    """
    raw, w, p = _load_root(path, "warehouse.yaml")
    _no_extra(w, raw, {"grid", "cell_size", "boxes", "box", "wall", "robot", "sensor", "physics"})
    grid = _take(w, raw, "grid")
    if not isinstance(grid, list) or len(grid) != 2:
        raise ConfigError(f"{w}:grid must be [rows, cols], integers >= 2, got {grid!r}.")
    rows, cols = (_count(f"{w}:grid[{i}]", g, minimum=2) for i, g in enumerate(grid))
    nb_raw = _take(w, raw, "boxes")
    if not isinstance(nb_raw, (list, tuple)) or len(nb_raw) != 2:
        raise ConfigError(f"{w}:boxes must be a [low, high] pair of counts, got {nb_raw!r}.")
    nb = tuple(_count(f"{w}:boxes[{i}]", b, minimum=0) for i, b in enumerate(nb_raw))
    if nb[0] > nb[1]:
        raise ConfigError(f"{w}:boxes has low {nb[0]} > high {nb[1]}; swap them.")
    box = _mapping(f"{w}:box", _take(w, raw, "box"))
    wall = _mapping(f"{w}:wall", _take(w, raw, "wall"))
    robot = _mapping(f"{w}:robot", _take(w, raw, "robot"))
    sensor = _mapping(f"{w}:sensor", _take(w, raw, "sensor"))
    phys = _mapping(f"{w}:physics", _take(w, raw, "physics"))
    cell = _number(f"{w}:cell_size", _take(w, raw, "cell_size"), positive=True)
    size = _field(w, "box", box, "size", positive=True)
    if size >= cell:
        raise ConfigError(f"{w}:box.size {size} must be smaller than cell_size {cell}.")
    elev = _take(f"{w}:sensor", sensor, "elevations")
    if not isinstance(elev, list) or not elev:
        raise ConfigError(f"{w}:sensor.elevations must be a non-empty list of degrees.")
    _no_extra(
        f"{w}:sensor",
        sensor,
        {"kind", "height", "max_range", "azimuths", "elevations", "noise", "camera"},
    )
    kind = sensor.get("kind", "scanner")
    if kind not in SENSOR_KINDS:
        raise ConfigError(
            f"{w}:sensor.kind must be one of {', '.join(SENSOR_KINDS)}, got {kind!r}."
        )
    cam = _mapping(f"{w}:sensor.camera", _take(f"{w}:sensor", sensor, "camera"))
    _no_extra(f"{w}:sensor.camera", cam, {"file", "binning", "pans", "tilt_deg", "floor_band"})
    camera = _warehouse_camera(w, cam, p.parent)
    tilt = _field(w, "sensor.camera", cam, "tilt_deg")
    if abs(tilt) >= 90.0:
        raise ConfigError(f"{w}:sensor.camera.tilt_deg must lie in (-90, 90), got {tilt}.")

    return WarehouseSpec(
        rows=rows,
        cols=cols,
        cell_size=cell,
        boxes=(nb[0], nb[1]),
        box_size=size,
        box_height=_field(w, "box", box, "height", positive=True),
        box_mass=_field(w, "box", box, "mass", positive=True),
        box_ground_friction=_field(w, "box", box, "ground_friction", positive=True),
        box_contact_friction=_field(w, "box", box, "contact_friction", nonneg=True),
        wall_height=_field(w, "wall", wall, "height", positive=True),
        wall_thickness=_field(w, "wall", wall, "thickness", positive=True),
        robot_radius=_field(w, "robot", robot, "radius", positive=True),
        robot_max_force=_field(w, "robot", robot, "max_force", positive=True),
        robot_speed=_field(w, "robot", robot, "speed", positive=True),
        robot_acceleration=_field(w, "robot", robot, "acceleration", positive=True),
        sensor_height=_field(w, "sensor", sensor, "height", positive=True),
        sensor_range=_field(w, "sensor", sensor, "max_range", positive=True),
        sensor_azimuths=_count_field(w, "sensor", sensor, "azimuths"),
        sensor_elevations=tuple(_number(f"{w}:sensor.elevations", e) for e in elev),
        sensor_noise=_field(w, "sensor", sensor, "noise", nonneg=True),
        control_rate=_field(w, "physics", phys, "control_rate", positive=True),
        substeps=_count_field(w, "physics", phys, "substeps"),
        iterations=_count_field(w, "physics", phys, "iterations"),
        friction_grid=_count_field(w, "physics", phys, "friction_grid"),
        collision_slop=_field(w, "physics", phys, "collision_slop", nonneg=True),
        sensor_kind=kind,
        camera=camera,
        camera_pans=_count_field(w, "sensor.camera", cam, "pans"),
        camera_tilt_deg=tilt,
        floor_band=_field(w, "sensor.camera", cam, "floor_band", positive=True),
    )


def _warehouse_camera(w: str, cam: dict[str, Any], folder: Path) -> CameraSpec:
    """The warehouse's head camera: the named camera file, binned (``sensor.camera``).

    The file is looked up next to the warehouse file, then in `worlds_dir()`.
    """
    from probaff.sim.camera import load_camera

    name = _take(f"{w}:sensor.camera", cam, "file")
    if not isinstance(name, str) or not name:
        raise ConfigError(f"{w}:sensor.camera.file must name a camera file, got {name!r}.")
    path = folder / name
    if not path.is_file():
        path = worlds_dir() / name
    if not path.is_file():
        raise ConfigError(
            f"{w}:sensor.camera.file {name!r} is neither next to {w} nor in {worlds_dir()}."
        )
    binning = _count_field(w, "sensor.camera", cam, "binning")
    spec = load_camera(path)
    try:
        return spec.binned(binning)
    except InputError as exc:
        raise ConfigError(f"{w}:sensor.camera.binning: {exc}") from None


@cache
def _catalogue_cached(path: str) -> dict[str, ObjectSpec]:
    p = Path(path)
    raw = _mapping(str(p), _read_yaml(p))
    out: dict[str, ObjectSpec] = {}
    for name, entry in raw.items():
        where = f"{p.name}:{name}"
        e = _mapping(where, entry)
        shape = _take(where, e, "shape")
        if shape == "box":
            _no_extra(
                where, e, {"shape", "size", "height", "mass", "ground_friction", "contact_friction"}
            )
            size_raw = _take(where, e, "size")
            if not isinstance(size_raw, list) or len(size_raw) != 2:
                raise ConfigError(f"{where}.size must be [length, width], got {size_raw!r}.")
            size = (
                _number(f"{where}.size[0]", size_raw[0], positive=True),
                _number(f"{where}.size[1]", size_raw[1], positive=True),
            )
            radius = 0.0
        elif shape == "circle":
            _no_extra(
                where,
                e,
                {"shape", "radius", "height", "mass", "ground_friction", "contact_friction"},
            )
            radius = _number(f"{where}.radius", _take(where, e, "radius"), positive=True)
            size = (2 * radius, 2 * radius)
        else:
            raise ConfigError(f"{where}.shape must be 'box' or 'circle', got {shape!r}.")
        out[str(name)] = ObjectSpec(
            name=str(name),
            shape=shape,
            size=size,
            radius=radius,
            height=_number(f"{where}.height", _take(where, e, "height"), positive=True),
            mass=_number(f"{where}.mass", _take(where, e, "mass"), positive=True),
            ground_friction=_number(
                f"{where}.ground_friction", _take(where, e, "ground_friction"), nonneg=True
            ),
            contact_friction=_number(
                f"{where}.contact_friction", _take(where, e, "contact_friction"), nonneg=True
            ),
        )
    if not out:
        raise ConfigError(f"{p} defines no objects.")
    return out


def load_catalogue(path: Path | None = None) -> dict[str, ObjectSpec]:
    """Load the object catalogue (``worlds/objects.yaml``).

    Args:
        path: Another catalogue file; defaults to the one in `worlds_dir()`.

    Returns:
        Mapping from object name to its spec.
    """
    return _catalogue_cached(str(path or worlds_dir() / "objects.yaml"))


def load_tabletop(path: Path | None = None) -> TabletopSpec:
    """Load and validate the tabletop world (``worlds/tabletop.yaml``).

    Args:
        path: Another world file; defaults to the one in `worlds_dir()`.
    """
    raw, w, p = _load_root(path, "tabletop.yaml")
    table = _mapping(f"{w}:table", _take(w, raw, "table"))
    arm = _mapping(f"{w}:arm", _take(w, raw, "arm"))
    ik = _mapping(f"{w}:arm.ik", _take(f"{w}:arm", arm, "ik"))
    grip = _mapping(f"{w}:gripper", _take(w, raw, "gripper"))
    phys = _mapping(f"{w}:physics", _take(w, raw, "physics"))
    push = _mapping(f"{w}:push", _take(w, raw, "push"))
    base = _take(f"{w}:arm", arm, "base_xyz")
    if not isinstance(base, list) or len(base) != 3:
        raise ConfigError(f"{w}:arm.base_xyz must be [x, y, z], got {base!r}.")
    opening = _field(w, "gripper", grip, "push_opening", positive=True)
    if opening > 0.15 + 1e-9:
        raise ConfigError(f"{w}:gripper.push_opening {opening} exceeds the 0.15 m finger span.")
    urdf = p.parent / str(_take(f"{w}:arm", arm, "urdf"))
    return TabletopSpec(
        table_size=_pair(f"{w}:table.size", _take(f"{w}:table", table, "size")),
        arm=ArmSpec(
            urdf=urdf,
            tcp_link=str(_take(f"{w}:arm", arm, "tcp_link")),
            base_xyz=tuple(_number(f"{w}:arm.base_xyz", b) for b in base),  # type: ignore[arg-type]
            base_yaw=_field(w, "arm", arm, "base_yaw"),
            push_height=_field(w, "arm", arm, "push_height", nonneg=True),
            pos_tolerance=_field(w, "arm.ik", ik, "pos_tolerance", positive=True),
            rot_tolerance=_field(w, "arm.ik", ik, "rot_tolerance", positive=True),
            max_iterations=_count_field(w, "arm.ik", ik, "max_iterations"),
            waypoint_spacing=_field(w, "arm.ik", ik, "waypoint_spacing", positive=True),
        ),
        gripper=GripperSpec(
            finger_radius=_field(w, "gripper", grip, "finger_radius", positive=True),
            push_opening=opening,
            mass=_field(w, "gripper", grip, "mass", positive=True),
            max_force=_field(w, "gripper", grip, "max_force", positive=True),
            max_torque=_field(w, "gripper", grip, "max_torque", positive=True),
            max_speed=_field(w, "gripper", grip, "max_speed", positive=True),
            contact_friction=_field(w, "gripper", grip, "contact_friction", nonneg=True),
        ),
        physics=PhysicsSpec(
            gravity=_field(w, "physics", phys, "gravity", positive=True),
            control_rate=_field(w, "physics", phys, "control_rate", positive=True),
            substeps=_count_field(w, "physics", phys, "substeps"),
            iterations=_count_field(w, "physics", phys, "iterations"),
            collision_slop=_field(w, "physics", phys, "collision_slop", nonneg=True),
            friction_grid=_count_field(w, "physics", phys, "friction_grid"),
        ),
        push_speed=_field(w, "push", push, "speed", positive=True),
        push_acceleration=_field(w, "push", push, "acceleration", positive=True),
        settle_time=_field(w, "push", push, "settle_time", nonneg=True),
        record_rate=_field(w, "push", push, "record_rate", positive=True),
    )


def list_scenes() -> list[str]:
    """Names of the scene templates in ``worlds/scenes/``."""
    return sorted(p.stem for p in (worlds_dir() / "scenes").glob("*.yaml"))


def _placement(
    where: str, raw: Any, catalogue: dict[str, ObjectSpec], first: bool
) -> PlacementSpec:
    e = _mapping(where, raw)
    _no_extra(where, e, {"choices", "x", "y", "along", "lateral", "yaw"})
    choices = _take(where, e, "choices")
    if not isinstance(choices, list) or not choices:
        raise ConfigError(f"{where}.choices must be a non-empty list of catalogue names.")
    for c in choices:
        if c not in catalogue:
            raise ConfigError(
                f"{where}: unknown object {c!r}; the catalogue has {sorted(catalogue)}."
            )
    yaw = _range(f"{where}.yaw", e.get("yaw", [-math.pi, math.pi]))
    if first:
        if "along" in e or "lateral" in e:
            raise ConfigError(
                f"{where}: the first object is placed by world x/y, not along/lateral."
            )
        return PlacementSpec(
            tuple(choices),
            x=_range(f"{where}.x", _take(where, e, "x")),
            y=_range(f"{where}.y", _take(where, e, "y")),
            yaw=yaw,
        )
    if ("x" in e or "y" in e) and ("along" in e or "lateral" in e):
        raise ConfigError(
            f"{where}: place a later object either by world x/y (and a world yaw) or by "
            "along/lateral in the push frame, not both."
        )
    if "x" in e or "y" in e:
        return PlacementSpec(
            tuple(choices),
            x=_range(f"{where}.x", _take(where, e, "x")),
            y=_range(f"{where}.y", _take(where, e, "y")),
            yaw=yaw,
        )
    return PlacementSpec(
        tuple(choices),
        along=_range(f"{where}.along", _take(where, e, "along")),
        lateral=_range(f"{where}.lateral", _take(where, e, "lateral")),
        yaw=yaw,
    )


def load_scene(name: str) -> SceneSpec:
    """Load a scene template by name.

    Args:
        name: A name from `list_scenes()`.

    Raises:
        ConfigError: For an unknown scene, an unknown object, or a malformed field.
    """
    path = worlds_dir() / "scenes" / f"{name}.yaml"
    if not path.is_file():
        raise ConfigError(f"unknown scene {name!r}; available scenes: {list_scenes()}.")
    catalogue = load_catalogue()
    raw = _mapping(path.name, _read_yaml(path))
    w = path.name
    _no_extra(w, raw, {"name", "description", "objects", "walls", "push", "randomise"})
    objs = _take(w, raw, "objects")
    if not isinstance(objs, list) or not objs:
        raise ConfigError(f"{w}: objects must be a non-empty list.")
    placements = tuple(
        _placement(f"{w}:objects[{i}]", o, catalogue, i == 0) for i, o in enumerate(objs)
    )
    walls = []
    for i, wr in enumerate(raw.get("walls") or []):
        ww = f"{w}:walls[{i}]"
        we = _mapping(ww, wr)
        _no_extra(ww, we, {"along", "lateral", "length", "angle"})
        walls.append(
            WallSpec(
                along=_range(f"{ww}.along", _take(ww, we, "along")),
                lateral=_range(f"{ww}.lateral", _take(ww, we, "lateral")),
                length=_number(f"{ww}.length", _take(ww, we, "length"), positive=True),
                angle=_range(f"{ww}.angle", we.get("angle", [0.0, 0.0])),
            )
        )
    pr = _mapping(f"{w}:push", _take(w, raw, "push"))
    _no_extra(f"{w}:push", pr, {"target", "distance", "direction", "lateral_offset", "start_gap"})
    target = _count(f"{w}:push.target", pr.get("target", 0), minimum=0)
    if target != 0:
        raise ConfigError(f"{w}:push.target must be 0 (the first object is the pushed one).")
    push = PushSpec(
        target=target,
        distance=_field(w, "push", pr, "distance", positive=True),
        direction=_range(f"{w}:push.direction", _take(f"{w}:push", pr, "direction")),
        lateral_offset=_range(f"{w}:push.lateral_offset", pr.get("lateral_offset", [0.0, 0.0])),
        start_gap=_range(f"{w}:push.start_gap", _take(f"{w}:push", pr, "start_gap"), nonneg=True),
    )
    rnd = _mapping(f"{w}:randomise", raw.get("randomise") or {})
    _no_extra(
        f"{w}:randomise",
        rnd,
        {"ground_friction_scale", "contact_friction_scale", "mass_scale", "support_load_variation"},
    )
    variation = _number(
        f"{w}:randomise.support_load_variation", rnd.get("support_load_variation", 0.0), nonneg=True
    )
    if variation >= 1.0:
        raise ConfigError(f"{w}:randomise.support_load_variation must be < 1, got {variation}.")
    return SceneSpec(
        name=str(raw.get("name", name)),
        description=str(raw.get("description", "")),
        objects=placements,
        walls=tuple(walls),
        push=push,
        ground_friction_scale=_range(
            f"{w}:randomise.ground_friction_scale",
            rnd.get("ground_friction_scale", [1.0, 1.0]),
            positive=True,
        ),
        contact_friction_scale=_range(
            f"{w}:randomise.contact_friction_scale",
            rnd.get("contact_friction_scale", [1.0, 1.0]),
            positive=True,
        ),
        mass_scale=_range(
            f"{w}:randomise.mass_scale", rnd.get("mass_scale", [1.0, 1.0]), positive=True
        ),
        support_load_variation=variation,
    )
