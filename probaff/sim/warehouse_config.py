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

__all__ = ["SENSOR_KINDS", "WALL_LAYOUTS", "WarehouseSpec", "load_warehouse"]

SENSOR_KINDS: tuple[str, ...] = ("camera", "scanner")
"""The warehouse robot's depth sensors: the head's depth camera (`probaff.sim.camera`), panned
round, or an idealised range scanner (Gaussian range noise only, 360 degrees)."""

WALL_LAYOUTS: tuple[str, ...] = ("line", "corner")
"""Shapes of a generated interior wall segment: a straight run of blocks along a row or a
column, or a run that turns by 90 degrees once (an L)."""


@dataclass(frozen=True)
class WarehouseSpec(CheckedSpec):
    """The grid warehouse (``worlds/warehouse.yaml``); see that file for the fields' meaning.

    The ``sensor_*`` range fields describe the idealised scanner; with ``sensor_kind ==
    "camera"`` the robot's sensor is `camera` (a `probaff.sim.camera.CameraSpec`) at
    ``sensor_height``, panned to ``camera_pans`` azimuths over 360 degrees and tilted down by
    ``camera_tilt_deg``; its returns below ``floor_band`` (m) count as floor.

    Interior walls (section ``interior_walls``) are blocks of a box's footprint and height
    standing in grid cells, which the sensor cannot tell from boxes: ``wall_segments`` is the
    range of segments a generated map holds, each ``wall_length`` blocks long in one of
    ``wall_layouts`` (`WALL_LAYOUTS`), and ``wall_blocks`` are ``(row, col)`` blocks standing
    in every map. Section ``box_rows``: ``box_row_share`` of a map's boxes stand in rows of
    ``box_row_length`` boxes along a row or a column, the rest anywhere free. The defaults
    (no interior walls, no rows) are the border-only warehouse.
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
    wall_segments: tuple[int, int] = (0, 0)
    wall_length: tuple[int, int] = (1, 1)
    wall_layouts: tuple[str, ...] = ("line",)
    wall_blocks: tuple[tuple[int, int], ...] = ()
    box_row_share: float = 0.0
    box_row_length: tuple[int, int] = (2, 2)

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
        self._check_layout()
        if self.sensor_kind == "camera":
            self._check_camera_view()

    def _check_layout(self) -> None:
        """Raise `ConfigError` unless the interior walls and box rows are well formed."""
        for name, low in (("wall_segments", 0), ("wall_length", 1), ("box_row_length", 1)):
            value = getattr(self, name)
            if wf.count_range(f"WarehouseSpec.{name}", value)[0] < low:
                raise ConfigError(f"WarehouseSpec.{name} must hold counts >= {low}, got {value!r}.")
        _wall_layouts("WarehouseSpec.wall_layouts", self.wall_layouts)
        share = self.box_row_share
        if isinstance(share, (bool, str, bytes)) or not isinstance(share, (int, float)):
            raise ConfigError(
                f"WarehouseSpec.box_row_share must be a share in [0, 1], got {share!r}."
            )
        if not 0.0 <= share <= 1.0:
            raise ConfigError(
                f"WarehouseSpec.box_row_share must be a share in [0, 1], got {share!r}."
            )
        _wall_blocks("WarehouseSpec.wall_blocks", self.wall_blocks, (self.rows, self.cols))

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
    wf.no_extra(
        w, raw, {"grid", "cell_size", "boxes", "sensor", "interior_walls", "box_rows", *_SECTIONS}
    )
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
        rows=rows,
        cols=cols,
        cell_size=cell,
        boxes=boxes,
        **values,
        **_sensor(w, raw, p.parent),
        **_layout(w, raw, (rows, cols)),
    )


def _layout(w: str, raw: dict[str, Any], shape: tuple[int, int]) -> dict[str, Any]:
    """The optional ``interior_walls`` and ``box_rows`` sections' `WarehouseSpec` fields.

    Raises:
        ConfigError: Naming the entry, for a malformed count range, an unknown layout, or a
            fixed wall block that is not a ``[row, col]`` cell inside the grid.
    """
    iw = f"{w}:interior_walls"
    walls = wf.optional_section(
        w, raw, "interior_walls", {"segments", "length", "layouts", "blocks"}
    )
    rows_ = wf.optional_section(w, raw, "box_rows", {"share", "length"})
    out: dict[str, Any] = {}
    if walls:
        out["wall_segments"] = wf.count_range(f"{iw}.segments", wf.take(iw, walls, "segments"))
        out["wall_length"] = wf.count_range(f"{iw}.length", wf.take(iw, walls, "length"))
        if out["wall_length"][0] < 1:
            raise ConfigError(f"{iw}.length must be at least 1 block, got {walls['length']!r}.")
        out["wall_layouts"] = _wall_layouts(f"{iw}.layouts", wf.take(iw, walls, "layouts"))
        out["wall_blocks"] = _wall_blocks(f"{iw}.blocks", walls.get("blocks") or [], shape)
    if rows_:
        br = f"{w}:box_rows"
        out["box_row_share"] = wf.probability(f"{br}.share", wf.take(br, rows_, "share"))
        out["box_row_length"] = wf.count_range(f"{br}.length", wf.take(br, rows_, "length"))
        if out["box_row_length"][0] < 1:
            raise ConfigError(f"{br}.length must be at least 1 box, got {rows_['length']!r}.")
    return out


def _wall_layouts(where: str, layouts: Any) -> tuple[str, ...]:
    """`layouts` (named `where`) as a tuple of `WALL_LAYOUTS` names.

    Raises:
        ConfigError: For an empty list or an unknown name.
    """
    if (
        not isinstance(layouts, (tuple, list))
        or not layouts
        or any(not isinstance(k, str) or k not in WALL_LAYOUTS for k in layouts)
    ):
        raise ConfigError(
            f"{where} must be a non-empty list of {', '.join(WALL_LAYOUTS)}, got {layouts!r}."
        )
    return tuple(layouts)


def _wall_blocks(where: str, blocks: Any, shape: tuple[int, int]) -> tuple[tuple[int, int], ...]:
    """`blocks` (named `where`) as distinct ``(row, col)`` cells inside a `shape` grid.

    Raises:
        ConfigError: Naming the entry and the fix.
    """
    if not isinstance(blocks, (list, tuple)):
        raise ConfigError(f"{where} must be a list of [row, col] cells, got {blocks!r}.")
    rows, cols = shape
    out: list[tuple[int, int]] = []
    for i, cell in enumerate(blocks):
        name = f"{where}[{i}]"
        if not isinstance(cell, (list, tuple)) or len(cell) != 2:
            raise ConfigError(f"{name} must be a [row, col] cell, got {cell!r}.")
        r, c = (wf.count(f"{name}[{j}]", v, minimum=0) for j, v in enumerate(cell))
        if r >= rows or c >= cols:
            raise ConfigError(
                f"{name} [{r}, {c}] lies outside the {rows} x {cols} grid (rows 0..{rows - 1}, "
                f"columns 0..{cols - 1}; the border walls need no blocks): move it inside or "
                "drop it."
            )
        if (r, c) in out:
            raise ConfigError(f"{name} repeats the wall block [{r}, {c}]; list each block once.")
        out.append((r, c))
    return tuple(out)


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
