"""Surface normals and curvature of a point cloud by k-nearest-neighbour PCA.

Every point's normal is the eigenvector of the smallest eigenvalue of the covariance of its
``k`` nearest neighbours (the point itself included, as PCL's ``NormalEstimation`` with
``setKSearch`` does); its curvature is PCL's surface variation
``lambda_min / (lambda_0 + lambda_1 + lambda_2)``, which lies in ``[0, 1/3]``: 0 on a plane,
larger on curved or noisy surfaces and at edges (0 where all k neighbours coincide). The
neighbours come from one ``scipy.spatial.cKDTree`` query; the covariances and the smallest
eigenpairs (in closed form, `numpy.linalg.eigh` where that is ill-conditioned) are batched.

Frames and units: points are in the robot frame (x forward, y left, z up), in metres; normals
are unit vectors in the same frame, curvature is dimensionless.

Thresholds and defaults:
    k = 30 neighbours: the neighbourhood size chapter 2's pipeline uses for region growing,
        and so also for the normals (our choice, so both see one neighbourhood).
    viewpoint = the origin: normals are flipped to point towards it (PCL's
        ``flipNormalTowardsViewpoint``, whose default viewpoint is also the origin); give the
        camera's position for a cloud seen from elsewhere.

Points with a NaN coordinate (depth-camera dropouts) are dropped: their rows of the result are
NaN and they are counted in `Normals.n_dropped`. Infinite coordinates are an error.

The neighbour lists are kept in the result (`Normals.neighbours`) so that region growing can
reuse them instead of querying the tree again: the query is the costliest step of both.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike
from scipy.spatial import cKDTree

from probaff._checks import check_count, check_finite, check_shape
from probaff.errors import InputError

__all__ = ["Normals", "estimate_normals"]

_WEAK_CROSS = 1e-6  # relative cross-product length below which eigh takes over
_CHUNK = 4096  # points per batched covariance block, bounding memory at (chunk, k, 3)


@dataclass(frozen=True)
class Normals:
    """Per-point normals and curvature; unpacks as ``normals, curvature = ...``.

    Attributes:
        normals: (N, 3) unit normals in the points' frame, oriented towards the viewpoint;
            NaN rows for dropped points.
        curvature: (N,) surface variation in ``[0, 1/3]``; NaN for dropped points.
        neighbours: (N, k) int64 indices into the cloud's rows of each point's k nearest
            valid neighbours, nearest first (the point itself is the first); -1 rows for
            dropped points.
    """

    normals: np.ndarray
    curvature: np.ndarray
    neighbours: np.ndarray

    def __iter__(self) -> Iterator[np.ndarray]:
        """Yield ``normals`` then ``curvature``, so the result unpacks as a pair."""
        yield self.normals
        yield self.curvature

    @property
    def valid(self) -> np.ndarray:
        """(N,) bool: True where the point had finite coordinates and got a normal."""
        return np.isfinite(self.curvature)

    @property
    def n_dropped(self) -> int:
        """The number of points dropped for a NaN coordinate."""
        return int(np.count_nonzero(~self.valid))


def _as_cloud(points: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """Return the cloud as float64 (N, 3) and its (N,) mask of rows without NaN."""
    pts = np.asarray(points, dtype=np.float64)
    check_shape("points", pts, (None, 3))
    if len(pts) == 0:
        raise InputError("points is an empty cloud; give at least k points of shape (N, 3).")
    if np.isinf(pts).any():
        raise InputError(
            "points contains infinite coordinates; replace them with NaN (dropped) or remove them."
        )
    valid = np.asarray(~np.isnan(pts).any(axis=1))
    return pts, valid


def _smallest_eigen(cov: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Smallest eigenpair of symmetric 3 x 3 matrices, in closed form.

    The eigenvalues come from the trigonometric solution of the characteristic cubic; the
    eigenvector of the smallest is the largest cross product of two rows of
    ``cov - lambda_min I``. Rows where that is ill-conditioned (a repeated smallest eigenvalue:
    the cross product is shorter than ``1e-6 (lambda_max - lambda_min)^2``, our choice, well
    above round-off) fall back to ``numpy.linalg.eigh``.

    Args:
        cov: (B, 3, 3) symmetric positive semi-definite matrices.

    Returns:
        (B, 3) eigenvalues in ascending order, clipped at 0, and (B, 3) unit eigenvectors of
        the smallest.
    """
    a = cov
    q = np.trace(a, axis1=1, axis2=2) / 3.0
    off = a[:, 0, 1] ** 2 + a[:, 0, 2] ** 2 + a[:, 1, 2] ** 2
    diag = (a[:, 0, 0] - q) ** 2 + (a[:, 1, 1] - q) ** 2 + (a[:, 2, 2] - q) ** 2
    p = np.sqrt((diag + 2.0 * off) / 6.0)
    safe_p = np.where(p > 0, p, 1.0)
    b = (a - q[:, None, None] * np.eye(3)) / safe_p[:, None, None]
    r = np.clip(np.linalg.det(b) / 2.0, -1.0, 1.0)
    phi = np.arccos(r) / 3.0
    big = q + 2.0 * p * np.cos(phi)
    small = q + 2.0 * p * np.cos(phi + 2.0 * np.pi / 3.0)
    mid = 3.0 * q - big - small
    evals = np.clip(np.stack([small, mid, big], axis=1), 0.0, None)
    m = a - small[:, None, None] * np.eye(3)
    crosses = np.stack(
        [np.cross(m[:, 0], m[:, 1]), np.cross(m[:, 0], m[:, 2]), np.cross(m[:, 1], m[:, 2])],
        axis=1,
    )  # (B, 3 pairs, 3)
    lengths = np.linalg.norm(crosses, axis=2)
    best = np.argmax(lengths, axis=1)
    rows = np.arange(len(a))
    vec = crosses[rows, best]
    length = lengths[rows, best]
    scale = np.maximum((big - small) ** 2, np.finfo(float).tiny)
    weak = length < _WEAK_CROSS * scale
    vec = vec / np.where(length > 0, length, 1.0)[:, None]
    if weak.any():
        w_vals, w_vecs = np.linalg.eigh(a[weak])
        evals[weak] = np.clip(w_vals, 0.0, None)
        vec[weak] = w_vecs[:, :, 0]
    return evals, vec


def _knn_pca(pts: np.ndarray, idx: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Smallest eigenpair of the covariance of each point's neighbourhood.

    The covariance is ``E[x x^T] - mu mu^T`` of the neighbours, without centring every
    neighbourhood; `pts` should be centred on the cloud's mean so that little precision is
    lost to cancellation.

    Args:
        pts: (M, 3) finite points, centred on the cloud's mean.
        idx: (B, k) indices into `pts` of each neighbourhood.

    Returns:
        (B, 3) eigenvalues in ascending order and (B, 3) unit normals (the eigenvector of the
        smallest eigenvalue).
    """
    k = idx.shape[1]
    nb = pts[idx]  # (B, k, 3)
    mu = np.matmul(np.full(k, 1.0 / k), nb)  # (B, 3)
    cov = np.matmul(nb.transpose(0, 2, 1), nb) / k - mu[:, :, None] * mu[:, None, :]
    return _smallest_eigen(cov)


def estimate_normals(
    points: ArrayLike, k: int = 30, *, viewpoint: ArrayLike | None = None
) -> Normals:
    """Estimate per-point normals and curvature by PCA of the k nearest neighbours.

    Args:
        points: (N, 3) points in the robot frame (m); rows with a NaN are dropped.
        k: Neighbourhood size, the point itself included (>= 3).
        viewpoint: (3,) position the normals point towards (m); default the origin.

    Returns:
        `Normals` with (N, 3) normals, (N,) curvature (NaN on dropped rows) and the (N, k)
        neighbour lists.

    Raises:
        InputError: For a cloud that is empty, not (N, 3), holds infinities or has fewer than
            `k` valid points; for a `k` that is not an integer >= 3; for a bad viewpoint.
    """
    k = check_count("k", k, minimum=3)
    pts, valid = _as_cloud(points)
    view = np.zeros(3) if viewpoint is None else np.asarray(viewpoint, dtype=np.float64)
    check_shape("viewpoint", view, (3,))
    check_finite("viewpoint", view)
    good = pts[valid]
    if len(good) < k:
        raise InputError(
            f"points has {len(good)} valid (non-NaN) point(s), fewer than k={k}; give a larger "
            "cloud or a smaller k."
        )
    tree = cKDTree(good)
    _, idx = tree.query(good, k=k)
    idx = np.asarray(idx, dtype=np.int64).reshape(len(good), k)
    normals = np.empty((len(good), 3))
    curvature = np.empty(len(good))
    centred = good - good.mean(axis=0)
    for start in range(0, len(good), _CHUNK):
        sl = slice(start, start + _CHUNK)
        evals, vecs = _knn_pca(centred, idx[sl])
        total = evals.sum(axis=1)
        curvature[sl] = np.where(total > 0, evals[:, 0] / np.where(total > 0, total, 1.0), 0.0)
        normals[sl] = vecs
    towards = view[None, :] - good
    flip = np.einsum("ij,ij->i", normals, towards) < 0
    normals[flip] *= -1.0
    out_n = np.full((len(pts), 3), np.nan)
    out_c = np.full(len(pts), np.nan)
    out_n[valid] = normals
    out_c[valid] = curvature
    rows = np.flatnonzero(valid)
    out_i = np.full((len(pts), k), -1, dtype=np.int64)
    out_i[valid] = rows[idx]
    return Normals(normals=out_n, curvature=out_c, neighbours=out_i)
