"""Chapter 4 push features: object (13), contact (42) and context (576), n = 631.

The thesis lists these three groups with exactly these sizes and prints their sum as 621; the
sum is 631, which is what is computed here.

All quantities are in the pushing frame (origin at the hand's start pose, z_p along the push,
y_p to its left, x_p down), so they do not change when the scene, its table and the push are
moved or turned together.

Columns:
    f_o (13): o1's cloud centroid (3); the quaternion ``(w, x, y, z)`` of o1's orientation in
        the pushing frame, a turn about x_p taken from the cloud's principal axis (4); the
        minimum and maximum of its points along x_p, y_p, z_p relative to the centroid (6).
    f_c (42): a Gaussian summary of the surfaces in a 20 x 10 x 10 cm volume at the hand
        (z_p in [0, 0.2], ``|y_p| <= 0.05``, up to 0.1 m above the table): every object point in
        it falls in a 1 cm voxel; each occupied voxel gives its mean position and unit mean
        normal (a 6-vector); the features are the mean (6) and the covariance (36, row-major)
        of those 6-vectors. An empty volume (a push that misses) gives zeros.
    f_x (576): a 12 x 12 grid of 5 cm cells over a 60 x 60 cm square centred on o1's centroid
        and aligned with the pushing frame (rows along z_p, columns along y_p); each cell is a
        one-hot of (object, obstacle, table, free). A cell is ``object`` or ``obstacle`` by the
        majority of the projected points of o1 versus other objects and walls when it holds at
        least 3 of them; otherwise ``table`` if its centre lies on the table, else ``free``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from probaff._checks import check_count
from probaff.data.queries import PushInputs
from probaff.features._common import PushClouds, chunked, meta_float, principal_yaw
from probaff.features.featureset import FeatureSet
from probaff.features.frames import points_to_push_frame
from probaff.features.requirements import FEATURE_REQUIREMENTS

__all__ = ["CONTEXT_CLASSES", "REQUIRES", "TableGeometry", "chapter4_features"]

REQUIRES = FEATURE_REQUIREMENTS["ch4"]
"""What `chapter4_features` reads: the clouds, the push, the walls and ``meta["push_height"]``
(``meta["table_size"]`` too when there, else a 1 x 0.8 m table)."""

CONTEXT_CLASSES = ("object", "obstacle", "table", "free")
_VOX = 0.01
_HAND_BOX = ((0.0, 0.20), (-0.05, 0.05), (0.0, 0.10))  # z_p, y_p, height above the table
_GRID, _CELL = 12, 0.05
_MIN_POINTS = 3
_WALL_STEP = 0.005


@dataclass(frozen=True)
class TableGeometry:
    """The table top: a rectangle in the world.

    Attributes:
        center: (2,) world xy of its centre.
        yaw: World yaw of its first side.
        size: Its extent along its own axes (m).
    """

    center: tuple[float, float] = (0.0, 0.0)
    yaw: float = 0.0
    size: tuple[float, float] = (1.0, 0.8)

    def contains(self, xy: np.ndarray) -> np.ndarray:
        """(...,) whether world points (..., 2) lie on the table."""
        c, s = np.cos(self.yaw), np.sin(self.yaw)
        rel = xy - np.asarray(self.center)
        u = rel[..., 0] * c + rel[..., 1] * s
        v = -rel[..., 0] * s + rel[..., 1] * c
        return (np.abs(u) <= 0.5 * self.size[0]) & (np.abs(v) <= 0.5 * self.size[1])


def _names() -> tuple[str, ...]:
    names = [f"f_o.centroid_{a}" for a in "xyz"] + [f"f_o.quat_{a}" for a in "wxyz"]
    names += [f"f_o.{m}_{a}" for m in ("min", "max") for a in "xyz"]
    names += [f"f_c.mean_{i}" for i in range(6)]
    names += [f"f_c.cov_{i}{j}" for i in range(6) for j in range(6)]
    names += [
        f"f_x.r{r}.c{c}.{k}" for r in range(_GRID) for c in range(_GRID) for k in CONTEXT_CLASSES
    ]
    return tuple(names)


def _object(c: PushClouds) -> np.ndarray:
    p = c.points[:, 0]  # (n, P, 3)
    centroid = p.mean(1)
    yaw = principal_yaw(p[..., 1], p[..., 2], np.ones(p.shape[:2], dtype=bool))
    # a turn by yaw from z_p towards y_p is a turn by yaw about x_p
    quat = np.stack([np.cos(yaw / 2), np.sin(yaw / 2), np.zeros_like(yaw), np.zeros_like(yaw)], -1)
    rel = p - centroid[:, None]
    return np.concatenate([centroid, quat, rel.min(1), rel.max(1)], axis=1)


def _contact(c: PushClouds) -> np.ndarray:
    n, K, P, _ = c.points.shape
    p = c.points.reshape(n, K * P, 3)
    nrm = c.normals.reshape(n, K * P, 3)
    h = c.height.reshape(n, K * P)
    (z0, z1), (y0, y1), (h0, h1) = _HAND_BOX
    inside = (
        (p[..., 2] >= z0)
        & (p[..., 2] < z1)
        & (p[..., 1] >= y0)
        & (p[..., 1] < y1)
        & (h >= h0)
        & (h < h1)
    )
    out = np.zeros((n, 42))
    sample, idx = np.nonzero(inside)
    if len(sample) == 0:
        return out
    q = p[sample, idx]
    vz = np.floor((q[:, 2] - z0) / _VOX).astype(np.int64)
    vy = np.floor((q[:, 1] - y0) / _VOX).astype(np.int64)
    vh = np.floor((h[sample, idx] - h0) / _VOX).astype(np.int64)
    key = ((sample * 20 + vz) * 10 + vy) * 10 + vh
    uniq, inv = np.unique(key, return_inverse=True)
    cnt = np.bincount(inv).astype(float)
    feats = (
        np.stack([np.bincount(inv, weights=v) for v in (*q.T, *nrm[sample, idx].T)], -1)
        / cnt[:, None]
    )
    norm = np.linalg.norm(feats[:, 3:], axis=1, keepdims=True)
    feats[:, 3:] /= np.maximum(norm, 1e-12)
    owner = uniq // (20 * 10 * 10)
    m = np.bincount(owner, minlength=n).astype(float)
    mean = (
        np.stack([np.bincount(owner, weights=feats[:, j], minlength=n) for j in range(6)], -1)
        / np.maximum(m, 1)[:, None]
    )
    dev = feats - mean[owner]
    outer = dev[:, :, None] * dev[:, None, :]
    cov = (
        np.stack(
            [
                np.bincount(owner, weights=outer[:, i, j], minlength=n)
                for i in range(6)
                for j in range(6)
            ],
            -1,
        )
        / np.maximum(m, 1)[:, None]
    )
    out[:, :6] = mean
    out[:, 6:] = cov
    return out


def _wall_points(walls: np.ndarray) -> np.ndarray:
    """(N, Q, 2) points every 5 mm along each push's walls (NaN padded)."""
    n = walls.shape[0]
    if walls.shape[1] == 0:
        return np.zeros((n, 0, 2))
    lengths = np.hypot(walls[..., 2] - walls[..., 0], walls[..., 3] - walls[..., 1])
    q = int(np.ceil(lengths.max() / _WALL_STEP)) + 1 if lengths.size else 1
    t = np.linspace(0.0, 1.0, q)
    a, b = walls[..., None, :2], walls[..., None, 2:]
    pts = a + t[None, None, :, None] * (b - a)  # (N, W, q, 2)
    return pts.reshape(n, -1, 2)


def chapter4_features(
    ds: PushInputs, table: TableGeometry | None = None, chunk: int = 512
) -> FeatureSet:
    """Compute the chapter 4 features of every push.

    Args:
        ds: A push dataset, or candidate `PushQueries` (clouds, walls and push poses are used).
        table: The table top in the world; by default the dataset's table, centred at the
            origin.
        chunk: Pushes processed at once (bounds memory); a positive integer.

    Returns:
        A (N, 631) `FeatureSet` with groups ``f_o``, ``f_c``, ``f_x``.

    Raises:
        InputError: For an empty dataset, a `chunk` that is not a positive integer, or a
            dataset that lacks an array or ``meta`` entry of `REQUIRES` (naming it).
    """
    chunk = check_count("chunk", chunk)
    REQUIRES.check(ds)
    if table is None:
        size = ds.meta.get("table_size", (1.0, 0.8))
        table = TableGeometry(size=(float(size[0]), float(size[1])))
    height = meta_float(ds, "push_height")
    origin_all, yaw_all = ds["push_origin"], ds["push_yaw"]
    walls_all = _wall_points(ds["walls"])
    starts = iter(range(0, len(ds), chunk))

    def context(c: PushClouds) -> np.ndarray:
        start = next(starts)
        rows = slice(start, start + len(c.distance))
        n, K, P, _ = c.points.shape
        centre = c.points[:, 0, :, 1:].mean(1)  # o1 centroid (y_p, z_p)
        walls = walls_all[rows]
        wq = walls.shape[1]
        wall_p = points_to_push_frame(
            np.concatenate([walls, np.zeros((n, wq, 1))], -1),
            origin_all[rows],
            yaw_all[rows],
            height,
        )[..., 1:]
        yz = np.concatenate([c.points[..., 1:].reshape(n, K * P, 2), wall_p], 1)
        is_obj = np.concatenate([np.ones((n, P), bool), np.zeros((n, (K - 1) * P + wq), bool)], 1)
        rel = yz - centre[:, None]
        col = np.floor(rel[..., 0] / _CELL + _GRID / 2).astype(np.int64)
        row = np.floor(rel[..., 1] / _CELL + _GRID / 2).astype(np.int64)
        ok = (col >= 0) & (col < _GRID) & (row >= 0) & (row < _GRID)
        cell = (np.arange(n)[:, None] * _GRID + row) * _GRID + col
        n_obj = np.bincount(cell[ok & is_obj], minlength=n * _GRID * _GRID)
        n_obs = np.bincount(cell[ok & ~is_obj], minlength=n * _GRID * _GRID)
        n_obj = n_obj.reshape(n, _GRID, _GRID)
        n_obs = n_obs.reshape(n, _GRID, _GRID)
        # cell centres back in the world, for the table test
        u = (np.arange(_GRID) + 0.5 - _GRID / 2) * _CELL
        cy = centre[:, 0, None, None] + u[None, None, :]  # columns along y_p
        cz = centre[:, 1, None, None] + u[None, :, None]  # rows along z_p
        yaw = yaw_all[rows][:, None, None]
        ox, oy = origin_all[rows, 0, None, None], origin_all[rows, 1, None, None]
        wx = ox + cz * np.cos(yaw) - cy * np.sin(yaw)
        wy = oy + cz * np.sin(yaw) + cy * np.cos(yaw)
        on_table = table.contains(np.stack([wx, wy], -1))
        label = np.where(on_table, 2, 3)
        occupied = np.maximum(n_obj, n_obs) >= _MIN_POINTS
        label = np.where(occupied, np.where(n_obj >= n_obs, 0, 1), label)
        return np.eye(4)[label].reshape(n, -1)

    def fn(c: PushClouds) -> np.ndarray:
        return np.concatenate([_object(c), _contact(c), context(c)], axis=1)

    values = chunked(ds, 631, fn, chunk)
    groups = {"f_o": slice(0, 13), "f_c": slice(13, 55), "f_x": slice(55, 631)}
    return FeatureSet(values, groups, _names())
