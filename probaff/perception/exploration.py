"""Frontier-based exploration of a warehouse map by the robot and its depth sensor.

The robot stands on cell centres and drives 4-connected, only through cells its occupancy grid
knows to be free (`OccupancyGrid.cell_states`). It scans where it starts; then, again and again,
it drives along a shortest path to the nearest reachable cell that it has not scanned from and
that touches (8-neighbourhood) a cell of unknown state, and scans there. It stops when no such
cell remains. It never touches a box. Ties between equally near cells go to the first in
row-major order, so a run depends only on the map, the start and the noise generator.

Every cell 4-connected to the start through free cells ends up known free: the union of two
neighbouring cells is a rectangle, so a scan from one cell's centre sees all of the other.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from probaff._checks import as_bool_array, check_shape
from probaff.errors import InputError
from probaff.grid import DIRECTION_OFFSETS
from probaff.perception.occupancy import FREE_SPACE, UNKNOWN, OccupancyGrid
from probaff.sim.depth import DepthSensor
from probaff.sim.warehouse import WarehouseMap
from probaff.sim.warehouse_config import WarehouseSpec

__all__ = ["Exploration", "explore", "grid_distances"]


@dataclass(frozen=True)
class Exploration:
    """The outcome of exploring one map.

    Attributes:
        grid: The occupancy grid after the last scan.
        points: (M, 3) world frame, the points of all scans merged.
        cells: (T, 2) int, the ``(row, col)`` of the robot at each scan, in order; the first is
            the start.
        path_length: Cells driven in all (4-connected moves).
    """

    grid: OccupancyGrid
    points: np.ndarray
    cells: np.ndarray
    path_length: int


def grid_distances(passable: np.ndarray, start: tuple[int, int]) -> np.ndarray:
    """Shortest 4-connected path lengths from a cell through passable cells (breadth first).

    Args:
        passable: (rows, cols) bool, the cells a path may use.
        start: ``(row, col)`` of the first cell; it counts as passable.

    Returns:
        (rows, cols) int, moves from `start`; -1 where no path reaches.
    """
    passable = as_bool_array("passable", passable)
    check_shape("passable", passable, (None, None))
    h, w = passable.shape
    dist = np.full((h, w), -1, dtype=np.int64)
    wave = np.zeros((h, w), dtype=bool)
    wave[start] = True
    step = 0
    while wave.any():
        dist[wave] = step
        padded = np.pad(wave, 1, constant_values=False)
        grown = np.zeros_like(wave)
        for dr, dc in DIRECTION_OFFSETS:
            grown |= padded[1 - dr : 1 - dr + h, 1 - dc : 1 - dc + w]
        wave = grown & passable & (dist < 0)
        step += 1
    return dist


def _touches_unknown(states: np.ndarray) -> np.ndarray:
    """(rows, cols) bool: cells with an unknown cell among their 8 neighbours."""
    h, w = states.shape
    padded = np.pad(states == UNKNOWN, 1, constant_values=False)
    out = np.zeros((h, w), dtype=bool)
    for dr in (-1, 0, 1):
        for dc in (-1, 0, 1):
            if dr or dc:
                out |= padded[1 + dr : 1 + dr + h, 1 + dc : 1 + dc + w]
    return out


def explore(
    spec: WarehouseSpec,
    m: WarehouseMap,
    start: tuple[int, int] | np.ndarray,
    rng: np.random.Generator,
    resolution: float = 0.25,
    free_fraction: float = 0.75,
) -> Exploration:
    """Explore a map from a start cell until no reachable frontier remains.

    Args:
        spec: The warehouse world (sensor model and obstacle sizes).
        m: The map; only the simulated sensor looks at it.
        start: ``(row, col)`` of a free cell where the robot starts.
        rng: Source of the sensor noise.
        resolution: Sub-cell side of the occupancy grid (m).
        free_fraction: Share of free sub-cells that makes a cell known free (and drivable).

    Returns:
        The grid, the merged cloud and the robot's scan positions.

    Raises:
        InputError: If `start` is not a (2,) cell inside the map or holds a box.
    """
    check_shape("start cell", start, (2,))
    start_cell = np.asarray(start)
    if not np.issubdtype(start_cell.dtype, np.integer):
        raise InputError(f"start cell must be integer (row, col), got {start_cell.tolist()}.")
    if not m.inside(start_cell):
        raise InputError(
            f"start cell {start_cell.tolist()} lies outside the {m.shape[0]} x {m.shape[1]} map."
        )
    here = (int(start_cell[0]), int(start_cell[1]))
    if m.occupancy[here]:
        raise InputError(f"start cell {here} holds a box; start the robot on a free cell.")
    sensor = DepthSensor(spec, m)
    grid = OccupancyGrid(m.shape, m.cell_size, resolution)
    scanned = np.zeros(m.shape, dtype=bool)
    clouds, cells, length = [], [], 0
    while True:
        scan = sensor.scan(m.cell_centre(np.array(here)), rng)
        grid.update(scan)
        clouds.append(scan.points)
        cells.append(here)
        scanned[here] = True
        states = grid.cell_states(free_fraction)
        dist = grid_distances(states == FREE_SPACE, here)
        goals = (dist >= 0) & ~scanned & _touches_unknown(states)
        if not goals.any():
            break
        cost = np.where(goals, dist, np.iinfo(np.int64).max)
        flat = int(np.argmin(cost))
        here = (flat // m.shape[1], flat % m.shape[1])
        length += int(dist[here])
    return Exploration(
        grid=grid, points=np.concatenate(clouds), cells=np.array(cells), path_length=length
    )
