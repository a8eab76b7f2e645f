"""Per-voxel geometric features of the explored warehouse, from its cloud and occupancy grid.

The world is cut into cubic voxels of one warehouse cell (side ``s``): voxel ``(r, c, l)`` spans
cell ``(r, c)`` and heights ``[l s, (l + 1) s)``; a 2 m box in 1 m cells has two voxels. Points
below ``floor_height`` are floor and left out; points above the top layer count in it. A voxel
is described when the occupancy grid marks its cell occupied (any occupied sub-cell) and it
holds at least ``min_points`` points; the rest of the cloud still enters the neighbour columns.

Columns (43), grouped (`FeatureSet.groups`):

* ``saliency`` (3): from the eigenvalues ``l0 >= l1 >= l2`` of the voxel's point covariance
  (m^2): ``scatter`` = l0, ``linear`` = l0 - l1, ``planar`` = l1 - l2.
* ``normal`` (3): absolute x, y, z components of the eigenvector of l2 (the surface normal,
  sign-free).
* ``span`` (3): extent of the points along x, y, z (m).
* ``centroid`` (3): point centroid minus the voxel centre, x, y, z (m).
* ``count`` (1): log(1 + number of points).
* ``layer`` (1): the layer index l.
* ``own`` (3): the free, occupied and unknown sub-cell fractions of the voxel's own cell.
* ``access`` (12): for each direction (up, down, left, right), the free, occupied and unknown
  fractions of the neighbouring cell that way; a wall beyond the map counts as observed and
  occupied (0, 1, 0).
* ``hmp_0.5`` and ``hmp_0.25`` (5 each): simplified multi-scale voxel normals. The voxel is cut
  into sub-voxels of side 0.5 m (0.25 m); each sub-voxel with at least 3 points gets a normal
  (smallest covariance eigenvector) oriented away from the cell's centre axis, and votes for the
  bin of its dominant direction: up (+y), down (-y), left (-x), right (+x), or z (vertical
  component largest). The columns are the fractions of votes per bin (0 with no votes).
* ``pairwise`` (4): for each direction, ``n / (n + n_self)`` with ``n`` the point count of
  the neighbouring voxel in the same layer and ``n_self`` this voxel's; 1 towards a wall.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from probaff._checks import check_count, check_finite, check_positive, check_shape
from probaff.features.featureset import FeatureSet
from probaff.features.requirements import FEATURE_REQUIREMENTS
from probaff.grid import DIRECTION_NAMES, DIRECTION_OFFSETS
from probaff.perception.occupancy import OccupancyGrid

__all__ = ["HMP_SCALES", "REQUIRES", "VoxelFeatures", "cell_features", "feature_names"]

REQUIRES = FEATURE_REQUIREMENTS["ch3.cells"]
"""What `cell_features` reads of a dataset: nothing; its inputs are a merged cloud and an
occupancy grid, checked as arguments."""

HMP_SCALES: tuple[float, ...] = (0.5, 0.25)  # sub-voxel sides (m) of the multi-scale normals
_STATES = ("free", "occupied", "unknown")
_HMP_BINS = (*DIRECTION_NAMES, "z")
_GROUPS: tuple[tuple[str, tuple[str, ...]], ...] = (
    ("saliency", ("scatter", "linear", "planar")),
    ("normal", ("normal_x", "normal_y", "normal_z")),
    ("span", ("span_x", "span_y", "span_z")),
    ("centroid", ("centroid_x", "centroid_y", "centroid_z")),
    ("count", ("log_count",)),
    ("layer", ("layer",)),
    ("own", tuple(f"own_{s}" for s in _STATES)),
    ("access", tuple(f"{d}_{s}" for d in DIRECTION_NAMES for s in _STATES)),
    *((f"hmp_{h:g}", tuple(f"hmp_{h:g}_{b}" for b in _HMP_BINS)) for h in HMP_SCALES),
    ("pairwise", tuple(f"pair_{d}" for d in DIRECTION_NAMES)),
)


def feature_names() -> tuple[tuple[str, ...], dict[str, slice]]:
    """The column names and groups of `cell_features`, in column order.

    Returns:
        ``(names, groups)``: (D,) names and the group name -> column slice mapping.
    """
    names: list[str] = []
    groups: dict[str, slice] = {}
    for group, cols in _GROUPS:
        groups[group] = slice(len(names), len(names) + len(cols))
        names.extend(cols)
    return tuple(names), groups


@dataclass(frozen=True)
class VoxelFeatures:
    """The features of the described voxels.

    Attributes:
        features: (V, D) features with named columns and groups.
        cells: (V, 2) int, ``(row, col)`` of each voxel's cell.
        layers: (V,) int, each voxel's layer.
    """

    features: FeatureSet
    cells: np.ndarray
    layers: np.ndarray


@dataclass(frozen=True)
class _Groups:
    """Points grouped by integer key, with their moments.

    Attributes:
        keys: (G,) sorted distinct keys.
        index: (N,) group of each point.
        counts: (G,) points per group.
        mean: (G, 3) centroid of each group.
        cov: (G, 3, 3) biased covariance of each group.
    """

    keys: np.ndarray
    index: np.ndarray
    counts: np.ndarray
    mean: np.ndarray
    cov: np.ndarray


def _group(keys: np.ndarray, points: np.ndarray) -> _Groups:
    uniq, index, counts = np.unique(keys, return_inverse=True, return_counts=True)
    g = len(uniq)
    sums = np.stack([np.bincount(index, points[:, a], g) for a in range(3)], -1)
    mean = sums / counts[:, None]
    d = points - mean[index]
    cov = np.empty((g, 3, 3))
    for a in range(3):
        for b in range(a, 3):
            cov[:, a, b] = cov[:, b, a] = np.bincount(index, d[:, a] * d[:, b], g) / counts
    return _Groups(uniq, index, counts, mean, cov)


def _sub_voxel_normals(
    points: np.ndarray,
    voxel: np.ndarray,
    corner: np.ndarray,
    axis_xy: np.ndarray,
    n_voxels: int,
    size: float,
    side: float,
) -> np.ndarray:
    """Histogram of sub-voxel normal directions per voxel.

    Args:
        points: (N, 3) world frame points of described voxels.
        voxel: (N,) index of each point's voxel in ``range(n_voxels)``.
        corner: (N, 3) world frame lower corner of each point's voxel.
        axis_xy: (N, 2) world frame xy of each point's cell centre.
        n_voxels: Number of voxels V.
        size: Voxel side (m).
        side: Sub-voxel side (m).

    Returns:
        (V, 5) vote fractions over (up, down, left, right, z).
    """
    n = max(1, round(size / side))
    sub = np.clip(np.floor((points - corner) / (size / n)).astype(np.int64), 0, n - 1)
    key = ((voxel * n + sub[:, 0]) * n + sub[:, 1]) * n + sub[:, 2]
    g = _group(key, points)
    ok = g.counts >= 3
    _, vecs = np.linalg.eigh(g.cov[ok])
    normal = vecs[:, :, 0]
    first = np.zeros(len(g.keys), dtype=np.int64)
    first[g.index] = np.arange(len(points))  # one point of each group (any will do)
    outward = g.mean[ok, :2] - axis_xy[first[ok]]
    normal *= np.where((normal[:, :2] * outward).sum(-1) < 0, -1.0, 1.0)[:, None]
    dirs = np.column_stack([DIRECTION_OFFSETS[:, 1], -DIRECTION_OFFSETS[:, 0]])  # world xy
    votes = np.where(
        np.abs(normal[:, 2]) >= np.abs(normal[:, :2]).max(-1),
        4,
        np.argmax(normal[:, :2] @ dirs.T, -1),
    )
    owner = voxel[first[ok]]
    hist = np.bincount(owner * 5 + votes, minlength=n_voxels * 5).reshape(n_voxels, 5)
    total = hist.sum(-1, keepdims=True)
    return hist / np.maximum(total, 1)


def _neighbours(
    fractions: np.ndarray,
    counts: np.ndarray,
    v_cell: np.ndarray,
    v_layer: np.ndarray,
    v_counts: np.ndarray,
) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """Per direction, the neighbouring cell's state fractions and the voxel pair's balance.

    Args:
        fractions: (rows, cols, 3) the grid's free / occupied / unknown fractions per cell.
        counts: (rows, cols, layers) points per voxel.
        v_cell: (V, 2) (row, col) of each described voxel.
        v_layer: (V,) its layer.
        v_counts: (V,) its points.

    Returns:
        ``(access, pair)``: for each of `DIRECTION_OFFSETS`, the (V, 3) fractions of the
        neighbouring cell (a cell beyond the map counts as occupied: a wall) and the (V,)
        share ``n_nb / (n_nb + n)`` of the neighbouring voxel's points (1 beyond the map).
    """
    rows, cols = fractions.shape[:2]
    walls = np.pad(fractions, ((1, 1), (1, 1), (0, 0)))
    walls[[0, -1], :, 1] = 1.0
    walls[:, [0, -1], 1] = 1.0
    padded_counts = np.pad(counts.astype(float), ((1, 1), (1, 1), (0, 0)))
    r1, c1 = v_cell[:, 0] + 1, v_cell[:, 1] + 1
    access, pair = [], []
    for dr, dc in DIRECTION_OFFSETS:
        access.append(walls[r1 + dr, c1 + dc])
        nb = padded_counts[r1 + dr, c1 + dc, v_layer]
        beyond_wall = ~((r1 + dr >= 1) & (r1 + dr <= rows) & (c1 + dc >= 1) & (c1 + dc <= cols))
        pair.append(np.where(beyond_wall, 1.0, nb / (nb + v_counts)))
    return access, pair


def cell_features(
    points: np.ndarray,
    grid: OccupancyGrid,
    n_layers: int = 2,
    floor_height: float = 0.05,
    min_points: int = 3,
) -> VoxelFeatures:
    """Features of the occupied voxels of an explored map.

    Args:
        points: (M, 3) world frame, the merged cloud of the exploration.
        grid: The occupancy grid of the same exploration.
        n_layers: Voxel layers above the floor (2 for 2 m boxes in 1 m cells); a positive
            integer.
        floor_height: Points below this height (m) are floor.
        min_points: Fewest points a described voxel holds (an integer >= 3).

    Returns:
        The features of every described voxel, row-major by cell then by layer; see the module
        docstring for the columns.

    Raises:
        InputError: For a cloud that is not (M, 3) or not finite, or bad settings.
    """
    check_shape("points", points, (None, 3))
    check_finite("points", points)
    check_positive("floor_height", floor_height, allow_zero=True)
    n_layers = check_count("n_layers", n_layers)
    min_points = check_count("min_points", min_points, minimum=3)
    rows, cols = grid.shape
    s = grid.cell_size
    pts = np.asarray(points, dtype=float)
    pts = pts[pts[:, 2] >= floor_height]
    col = np.floor(pts[:, 0] / s).astype(np.int64)
    row = rows - 1 - np.floor(pts[:, 1] / s).astype(np.int64)
    inside = (row >= 0) & (row < rows) & (col >= 0) & (col < cols)
    pts, row, col = pts[inside], row[inside], col[inside]
    layer = np.clip(np.floor(pts[:, 2] / s).astype(np.int64), 0, n_layers - 1)
    counts = np.bincount(
        (row * cols + col) * n_layers + layer, minlength=rows * cols * n_layers
    ).reshape(rows, cols, n_layers)

    fractions = grid.cell_fractions()
    occupied_cell = fractions[..., 1] > 0
    keep = occupied_cell[row, col] & (counts[row, col, layer] >= min_points)
    pts, row, col, layer = pts[keep], row[keep], col[keep], layer[keep]
    names, groups = feature_names()
    if not len(pts):
        return VoxelFeatures(
            features=FeatureSet(np.empty((0, len(names))), groups, names),
            cells=np.empty((0, 2), dtype=np.int64),
            layers=np.empty(0, dtype=np.int64),
        )
    g = _group((row * cols + col) * n_layers + layer, pts)
    v_layer = g.keys % n_layers
    v_cell = np.column_stack([(g.keys // n_layers) // cols, (g.keys // n_layers) % cols])
    centre = np.column_stack(
        [(v_cell[:, 1] + 0.5) * s, (rows - v_cell[:, 0] - 0.5) * s, (v_layer + 0.5) * s]
    )

    evals, evecs = np.linalg.eigh(g.cov)  # ascending: l2, l1, l0
    l2, l1, l0 = evals[:, 0], evals[:, 1], evals[:, 2]
    order = np.argsort(g.index, kind="stable")
    starts = np.concatenate([[0], np.cumsum(g.counts)[:-1]])
    span = np.maximum.reduceat(pts[order], starts, 0) - np.minimum.reduceat(pts[order], starts, 0)

    access, pair = _neighbours(fractions, counts, v_cell, v_layer, g.counts)

    hmp = [
        _sub_voxel_normals(
            pts, g.index, (centre - 0.5 * s)[g.index], centre[g.index, :2], len(g.keys), s, side
        )
        for side in HMP_SCALES
    ]
    values = np.column_stack(
        [
            l0,
            l0 - l1,
            l1 - l2,
            np.abs(evecs[:, :, 0]),
            span,
            g.mean - centre,
            np.log1p(g.counts),
            v_layer,
            fractions[v_cell[:, 0], v_cell[:, 1]],
            *access,
            *hmp,
            *pair,
        ]
    )
    return VoxelFeatures(features=FeatureSet(values, groups, names), cells=v_cell, layers=v_layer)
