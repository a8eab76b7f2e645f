"""The grid warehouse's world file (``worlds/warehouse.yaml``).

Covered by tests/sim/test_sim_warehouse.py.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from probaff.errors import ConfigError, InputError
from probaff.sim import world_files as wf
from probaff.sim.camera import CameraSpec, load_camera
from probaff.sim.world_files import CheckedSpec

__all__ = ["SENSOR_KINDS", "WarehouseSpec", "load_warehouse"]

SENSOR_KINDS: tuple[str, ...] = ("camera", "scanner")
"""The warehouse robot's depth sensors: the head's depth camera (`probaff.sim.camera`), panned
round, or an idealised range scanner (Gaussian range noise only, 360 degrees)."""


@dataclass(frozen=True)
class WarehouseSpec(CheckedSpec):
    """The grid warehouse (``worlds/warehouse.yaml``); see that file for the fields' meaning.

    The ``sensor_*`` range fields describe the idealised scanner; with ``sensor_kind ==
    "camera"`` the robot's sensor is `camera` (a `probaff.sim.camera.CameraSpec`) at
    ``sensor_height``, panned to ``camera_pans`` azimuths over 360 degrees and tilted down by
    ``camera_tilt_deg``; its returns below ``floor_band`` (m) count as floor.
    """

    POSITIVE = (
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
    )
    NONNEG = ("box_contact_friction", "sensor_noise", "collision_slop")
    COUNTS = ("sensor_azimuths", "substeps", "iterations", "friction_grid", "camera_pans")

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
        if self.sensor_kind == "camera" and not isinstance(self.camera, CameraSpec):
            raise ConfigError(
                "WarehouseSpec.camera must be a CameraSpec (see load_camera) when "
                f"sensor_kind is 'camera', got {type(self.camera).__name__}."
            )
        tilt = self.camera_tilt_deg
        if isinstance(tilt, (bool, str, bytes)) or not isinstance(tilt, (int, float)):
            raise ConfigError(
                f"WarehouseSpec.camera_tilt_deg must be a number of degrees, got {tilt!r}."
            )
        self._check_elevations()
        if not (math.isfinite(self.camera_tilt_deg) and abs(self.camera_tilt_deg) < 90.0):
            raise ConfigError(
                f"WarehouseSpec.camera_tilt_deg must lie in (-90, 90) degrees, got "
                f"{self.camera_tilt_deg!r}."
            )
        super().__post_init__()
        if self.sensor_kind == "camera":
            self._check_camera_view()

    def _check_elevations(self) -> None:
        """Raise `ConfigError` unless the scanner's elevations are angles in [-90, 90] deg."""
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


def _grid_and_boxes(w: str, raw: dict[str, Any]) -> tuple[int, int, tuple[int, int]]:
    """``(rows, cols, (fewest boxes, most boxes))`` of the warehouse file's top level."""
    grid = wf.take(w, raw, "grid")
    if not isinstance(grid, list) or len(grid) != 2:
        raise ConfigError(f"{w}:grid must be [rows, cols], integers >= 2, got {grid!r}.")
    rows, cols = (wf.count(f"{w}:grid[{i}]", g, minimum=2) for i, g in enumerate(grid))
    nb_raw = wf.take(w, raw, "boxes")
    if not isinstance(nb_raw, (list, tuple)) or len(nb_raw) != 2:
        raise ConfigError(f"{w}:boxes must be a [low, high] pair of counts, got {nb_raw!r}.")
    nb = tuple(wf.count(f"{w}:boxes[{i}]", b, minimum=0) for i, b in enumerate(nb_raw))
    if nb[0] > nb[1]:
        raise ConfigError(f"{w}:boxes has low {nb[0]} > high {nb[1]}; swap them.")
    return rows, cols, (nb[0], nb[1])


def _sensor(w: str, raw: dict[str, Any], folder: Path) -> dict[str, Any]:
    """The ``sensor`` section's `WarehouseSpec` fields."""
    s = f"{w}:sensor"
    sensor = wf.section(
        w,
        raw,
        "sensor",
        {"kind", "height", "max_range", "azimuths", "elevations", "noise", "camera"},
    )
    elev = wf.take(s, sensor, "elevations")
    if not isinstance(elev, list) or not elev:
        raise ConfigError(f"{w}:sensor.elevations must be a non-empty list of degrees.")
    kind = sensor.get("kind", "scanner")
    if kind not in SENSOR_KINDS:
        raise ConfigError(
            f"{w}:sensor.kind must be one of {', '.join(SENSOR_KINDS)}, got {kind!r}."
        )
    c = f"{s}.camera"
    cam = wf.section(s, sensor, "camera", {"file", "binning", "pans", "tilt_deg", "floor_band"})
    camera = _warehouse_camera(w, cam, folder)
    tilt = wf.number_field(c, cam, "tilt_deg")
    if abs(tilt) >= 90.0:
        raise ConfigError(f"{w}:sensor.camera.tilt_deg must lie in (-90, 90), got {tilt}.")
    return {
        "sensor_height": wf.number_field(s, sensor, "height", positive=True),
        "sensor_range": wf.number_field(s, sensor, "max_range", positive=True),
        "sensor_azimuths": wf.count_field(s, sensor, "azimuths"),
        "sensor_elevations": tuple(wf.number(f"{s}.elevations", e) for e in elev),
        "sensor_noise": wf.number_field(s, sensor, "noise", nonneg=True),
        "sensor_kind": kind,
        "camera": camera,
        "camera_pans": wf.count_field(c, cam, "pans"),
        "camera_tilt_deg": tilt,
        "floor_band": wf.number_field(c, cam, "floor_band", positive=True),
    }


_SECTIONS = {
    "box": {k: f"box_{k}" for k in ("size", "height", "mass", "ground_friction")}
    | {"contact_friction": "box_contact_friction"},
    "wall": {k: f"wall_{k}" for k in ("height", "thickness")},
    "robot": {k: f"robot_{k}" for k in ("radius", "max_force", "speed", "acceleration")},
    "physics": {
        k: k for k in ("control_rate", "substeps", "iterations", "friction_grid", "collision_slop")
    },
}
"""The plain sections of ``worlds/warehouse.yaml``: section -> key -> `WarehouseSpec` field."""


def load_warehouse(path: Path | None = None) -> WarehouseSpec:
    """Load and validate the warehouse world (``worlds/warehouse.yaml``).

    Args:
        path: Another warehouse file; defaults to the one in `worlds_dir()`.
    """
    raw, w, p = wf.load_root(path, "warehouse.yaml")
    wf.no_extra(w, raw, {"grid", "cell_size", "boxes", "sensor", *_SECTIONS})
    rows, cols, boxes = _grid_and_boxes(w, raw)
    cell = wf.number_field(w, raw, "cell_size", positive=True)
    values: dict[str, Any] = {}
    for key, names in _SECTIONS.items():
        values.update(WarehouseSpec.read_fields(f"{w}:{key}", wf.section(w, raw, key), names))
    if values["box_size"] >= cell:
        raise ConfigError(
            f"{w}:box.size {values['box_size']} must be smaller than cell_size {cell}."
        )
    return WarehouseSpec(
        rows=rows, cols=cols, cell_size=cell, boxes=boxes, **values, **_sensor(w, raw, p.parent)
    )


def _warehouse_camera(w: str, cam: dict[str, Any], folder: Path) -> CameraSpec:
    """The warehouse's head camera: the named camera file, binned (``sensor.camera``).

    The file is looked up next to the warehouse file, then in `wf.worlds_dir()`.
    """
    name = wf.take(f"{w}:sensor.camera", cam, "file")
    if not isinstance(name, str) or not name:
        raise ConfigError(f"{w}:sensor.camera.file must name a camera file, got {name!r}.")
    path = folder / name
    if not path.is_file():
        path = wf.worlds_dir() / name
    if not path.is_file():
        raise ConfigError(
            f"{w}:sensor.camera.file {name!r} is neither next to {w} nor in {wf.worlds_dir()}."
        )
    binning = wf.count_field(f"{w}:sensor.camera", cam, "binning")
    spec = load_camera(path)
    try:
        return spec.binned(binning)
    except InputError as exc:
        raise ConfigError(f"{w}:sensor.camera.binning: {exc}") from None
