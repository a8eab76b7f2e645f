"""A 2-D occupancy grid of the warehouse floor, built by tracing the sensor's horizontal rays.

The grid covers the map extent ``[0, cols s] x [0, rows s]`` (world frame, cell size ``s``) with
square sub-cells of side ``resolution``; ``k = s / resolution`` sub-cells per warehouse cell
along each axis. Sub-cells are indexed ``[i, j]`` like the map: row 0 is the top (largest y),
so warehouse cell ``(r, c)`` holds sub-cells ``[r k:(r + 1) k, c k:(c + 1) k]``.

Every horizontal ray of a `DepthScan` marks the sub-cells it crosses as passed (free evidence)
up to ``margin`` short of its end and, if it hit a surface, the sub-cell ``hit_offset`` beyond
its end as hit (occupied evidence). Both offsets keep noisy end points on the right side of a
surface: ``margin`` (a few range-noise deviations) stops the free trace before the surface, and
``hit_offset`` (no more than the gap between a box and its cell border) moves hits on a wall just
outside the grid out of the cells along the wall while hits on a box face stay in the box's
cell. A sub-cell is unknown until some ray passed or hit it, occupied when it was hit more often
than passed, and free otherwise.
"""

from __future__ import annotations

import numpy as np

from probaff._checks import check_count, check_finite, check_positive, check_shape
from probaff.errors import InputError
from probaff.grid import DIRECTION_OFFSETS
from probaff.sim.depth import DepthScan

__all__ = ["FREE_SPACE", "OCCUPIED", "UNKNOWN", "OccupancyGrid"]

UNKNOWN, FREE_SPACE, OCCUPIED = 0, 1, 2  # sub-cell and cell states


def _next_to(mask: np.ndarray) -> np.ndarray:
    """(H, W) bool: entries with a 4-neighbour set in `mask` (H, W); outside counts as unset."""
    padded = np.pad(mask, 1, constant_values=False)
    h, w = mask.shape
    out = np.zeros_like(mask)
    for dr, dc in DIRECTION_OFFSETS:
        out |= padded[1 + dr : 1 + dr + h, 1 + dc : 1 + dc + w]
    return out


class OccupancyGrid:
    """Free/occupied/unknown sub-cells over a warehouse map.

    Args:
        shape: ``(rows, cols)`` of the warehouse map, positive integers.
        cell_size: Side of a warehouse cell (m).
        resolution: Side of a sub-cell (m); must divide `cell_size`.
        margin: How far short of a ray's end the free trace stops (m).
        hit_offset: How far beyond a hitting ray's end its hit is marked (m).

    Attributes:
        passes: (rows k, cols k) int, how many rays crossed each sub-cell.
        hits: (rows k, cols k) int, how many rays ended in each sub-cell.

    Raises:
        InputError: For a non-positive size, a shape that is not two positive integers, or a
            resolution that does not divide the cell.
    """

    def __init__(
        self,
        shape: tuple[int, int],
        cell_size: float = 1.0,
        resolution: float = 0.25,
        margin: float = 0.04,
        hit_offset: float = 0.02,
    ) -> None:
        check_positive("cell_size", cell_size)
        check_positive("resolution", resolution)
        check_positive("margin", margin, allow_zero=True)
        check_positive("hit_offset", hit_offset, allow_zero=True)
        if len(shape) != 2:
            raise InputError(f"the grid shape must be (rows, cols), got {shape}.")
        rows, cols = (check_count(f"shape[{i}]", v) for i, v in enumerate(shape))
        k = round(cell_size / resolution)
        if k < 1 or abs(k * resolution - cell_size) > 1e-9 * cell_size:
            raise InputError(
                f"resolution {resolution} must divide cell_size {cell_size} a whole number of "
                "times (e.g. 0.25 for 1 m cells)."
            )
        self.shape = (rows, cols)
        self.cell_size = float(cell_size)
        self.resolution = float(resolution)
        self.margin = float(margin)
        self.hit_offset = float(hit_offset)
        self.per_cell = k
        self.passes = np.zeros((rows * k, cols * k), dtype=np.int64)
        self.hits = np.zeros((rows * k, cols * k), dtype=np.int64)

    @property
    def fine_shape(self) -> tuple[int, int]:
        """``(rows k, cols k)`` of the sub-cell array."""
        return self.passes.shape

    def _grid_coords(self, xy: np.ndarray) -> np.ndarray:
        """Continuous ``(column, row)`` sub-cell coordinates (..., 2) of world xy (..., 2)."""
        height = self.shape[0] * self.cell_size
        return np.stack([xy[..., 0], height - xy[..., 1]], -1) / self.resolution

    def update(self, scan: DepthScan) -> None:
        """Trace the horizontal rays of a scan into the grid.

        Args:
            scan: A scan taken inside this grid's map.

        Raises:
            InputError: For a scan of inconsistent shapes or with non-finite values.
        """
        check_shape("scan origin", scan.origin, (3,))
        check_shape("scan ends", scan.ends, (None, 2))
        check_shape("scan hits", scan.hits, (len(scan.ends),))
        check_finite("scan ends", scan.ends)
        check_finite("scan origin", scan.origin)
        origin = np.asarray(scan.origin[:2], dtype=float)
        ends = np.asarray(scan.ends, dtype=float)
        hits = np.asarray(scan.hits, dtype=bool)
        delta = ends - origin
        length = np.hypot(delta[:, 0], delta[:, 1])
        unit = delta / np.maximum(length, 1e-12)[:, None]
        free_len = np.where(hits, np.maximum(length - self.margin, 0.0), length)
        self._trace(origin, unit, free_len)
        beyond = origin + (length + self.hit_offset)[hits, None] * unit[hits]
        ij = self._inside_indices(np.floor(self._grid_coords(beyond)).astype(np.int64))
        np.add.at(self.hits, ij, 1)

    def _inside_indices(self, colrow: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Row and column index arrays of the integer ``(column, row)`` (N, 2) inside the grid."""
        n_i, n_j = self.fine_shape
        ok = (colrow[:, 0] >= 0) & (colrow[:, 0] < n_j) & (colrow[:, 1] >= 0) & (colrow[:, 1] < n_i)
        return colrow[ok, 1], colrow[ok, 0]

    def _trace(self, origin: np.ndarray, unit: np.ndarray, length: np.ndarray) -> None:
        """Add one pass to every sub-cell each segment crosses (exact grid traversal).

        Args:
            origin: (2,) world xy shared by the segments.
            unit: (A, 2) world unit directions.
            length: (A,) segment lengths (m).
        """
        if not len(length) or length.max() <= 0.0:
            return
        g0 = self._grid_coords(origin)
        v = np.stack([unit[:, 0], -unit[:, 1]], -1) / self.resolution  # grid units per metre
        n = int(np.ceil(length.max() / self.resolution)) + 2
        steps = np.arange(1, n + 1)
        crossings = []
        for axis in range(2):
            va = v[:, axis : axis + 1]
            base = np.where(va > 0, np.floor(g0[axis]), np.ceil(g0[axis]))
            lines = base + np.sign(va) * steps  # (A, n) grid lines ahead of the origin
            with np.errstate(divide="ignore", invalid="ignore"):
                t = (lines - g0[axis]) / va
            crossings.append(np.where((va != 0) & (t < length[:, None]), t, np.inf))
        t = np.sort(np.concatenate([np.zeros((len(length), 1)), *crossings, length[:, None]], 1), 1)
        a, b = t[:, :-1], t[:, 1:]
        seg = np.isfinite(b) & (b > a)
        ray, k = np.nonzero(seg)
        mid = 0.5 * (a[ray, k] + b[ray, k])
        cells = np.floor(g0 + mid[:, None] * v[ray]).astype(np.int64)
        i, j = self._inside_indices(cells)
        flat = np.bincount(i * self.fine_shape[1] + j, minlength=self.passes.size)
        self.passes += flat.reshape(self.fine_shape)

    @property
    def state(self) -> np.ndarray:
        """(rows k, cols k) int8 sub-cell states: `UNKNOWN`, `FREE_SPACE` or `OCCUPIED`."""
        out = np.full(self.fine_shape, UNKNOWN, dtype=np.int8)
        out[self.passes > 0] = FREE_SPACE
        out[self.hits > self.passes] = OCCUPIED
        return out

    def cell_fractions(self) -> np.ndarray:
        """Per warehouse cell, the fractions of its sub-cells in each state.

        Returns:
            (rows, cols, 3) float, the free, occupied and unknown fractions (summing to 1).
        """
        rows, cols = self.shape
        k = self.per_cell
        blocks = self.state.reshape(rows, k, cols, k)
        return np.stack([(blocks == s).mean((1, 3)) for s in (FREE_SPACE, OCCUPIED, UNKNOWN)], -1)

    def cell_states(self, free_fraction: float = 0.75) -> np.ndarray:
        """Per warehouse cell state.

        A cell is occupied if any of its sub-cells is, free if none is and at least
        `free_fraction` of them are free, and unknown otherwise.

        Args:
            free_fraction: Share of free sub-cells that makes a cell known free.

        Returns:
            (rows, cols) int8 of `UNKNOWN`, `FREE_SPACE` or `OCCUPIED`.
        """
        f = self.cell_fractions()
        out = np.full(self.shape, UNKNOWN, dtype=np.int8)
        out[(f[..., 1] == 0.0) & (f[..., 0] >= free_fraction)] = FREE_SPACE
        out[f[..., 1] > 0.0] = OCCUPIED
        return out

    def frontier(self) -> np.ndarray:
        """Free sub-cells with an unknown 4-neighbour inside the grid.

        Returns:
            (rows k, cols k) bool.
        """
        st = self.state
        return (st == FREE_SPACE) & _next_to(st == UNKNOWN)

    def cell_frontier(self, free_fraction: float = 0.75) -> np.ndarray:
        """Warehouse cells known free with a 4-neighbour of unknown state inside the map.

        Args:
            free_fraction: As in `cell_states`.

        Returns:
            (rows, cols) bool.
        """
        st = self.cell_states(free_fraction)
        return (st == FREE_SPACE) & _next_to(st == UNKNOWN)
