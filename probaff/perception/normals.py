"""Surface normals and curvature of a point cloud by k-nearest-neighbour PCA.

Every point's normal is the eigenvector of the smallest eigenvalue of the covariance of its
``k`` nearest neighbours (the point itself included, as PCL's ``NormalEstimation`` with
``setKSearch`` does); its curvature is PCL's surface variation
``lambda_min / (lambda_0 + lambda_1 + lambda_2)``, which lies in ``[0, 1/3]``: 0 on a plane,
larger on curved or noisy surfaces and at edges (0 where all k neighbours coincide). The
neighbours come from one ``scipy.spatial.cKDTree`` query with its default build (leaf size 16,
balanced): other build options or a distance bound return the same distances but break ties
differently, and so change some neighbour lists. The covariances (of each neighbourhood shifted
by the point itself, so no precision is lost to cancellation) and the smallest eigenpairs (in
closed form, `numpy.linalg.eigh` where that is ill-conditioned) are batched on flat per-entry
arrays; they agree with ``numpy.cov`` followed by ``numpy.linalg.eigh`` to about 1e-13.

Frames and units: points are in the robot frame (x forward, y left, z up), in metres; normals
are unit vectors in the same frame, curvature is dimensionless.

Thresholds and defaults:
    k = 30 neighbours: the neighbourhood size chapter 2's pipeline uses for region growing,
        and so also for the normals (our choice, so both see one neighbourhood).
    viewpoint = the origin: normals are flipped to point towards it (PCL's
        ``flipNormalTowardsViewpoint``, whose default viewpoint is also the origin); give the
        camera's position for a cloud seen from elsewhere.
    eigh fallback: where the closed form's cross product is shorter than
        ``1e-6 (lambda_max - lambda_min)^2`` or ``lambda_mid - lambda_min`` is at most
        ``0.05 (lambda_max - lambda_min)`` (our choices; see `_smallest_eigen`).
    2048 points per batch: bounds the temporaries at three (2048, k) arrays (our choice, the
        fastest of 1024 to 8192 on a 320 x 240 scan).

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

from probaff._checks import as_float_array, check_count, check_finite, check_shape
from probaff.errors import InputError

__all__ = ["Normals", "estimate_normals"]

_WEAK_CROSS = 1e-6  # relative cross-product length below which eigh takes over
_CLOSE_GAP = 0.05  # relative gap lambda_mid - lambda_min below which eigh takes over
_CHUNK = 2048  # points per batched covariance block, bounding memory at 3 (chunk, k) arrays
_PAIRS = ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))  # the distinct entries of a 3 x 3
_Cov = tuple[np.ndarray, ...]  # (c00, c01, c02, c11, c12, c22), each (B,)


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
    pts = as_float_array("points", points)
    check_shape("points", pts, (None, 3))
    if len(pts) == 0:
        raise InputError("points is an empty cloud; give at least k points of shape (N, 3).")
    if np.isinf(pts).any():
        raise InputError(
            "points contains infinite coordinates; replace them with NaN (dropped) or remove them."
        )
    valid = np.asarray(~np.isnan(pts).any(axis=1))
    return pts, valid


def _smallest_eigen(cov: _Cov) -> tuple[np.ndarray, np.ndarray]:
    """Smallest eigenpair of symmetric 3 x 3 matrices, in closed form.

    The eigenvalues come from the trigonometric solution of the characteristic cubic; the
    eigenvector of the smallest is the largest cross product of two rows of
    ``cov - lambda_min I``. Rows where that is ill-conditioned fall back to
    ``numpy.linalg.eigh``: a repeated smallest eigenvalue (the cross product is shorter than
    ``1e-6 (lambda_max - lambda_min)^2``, our choice, well above round-off) or a nearly repeated
    one (``lambda_mid - lambda_min <= 0.05 (lambda_max - lambda_min)``, our choice: there the
    arccos of the cubic's solution amplifies round-off, to about 3e-12 in the normal at a gap of
    0.003 on an office scan, while above 0.05 the closed form agrees with ``eigh`` to about 1e-14;
    about 0.3 % of a scan's points fall back). Every step works on the six distinct
    entries as flat (B,) arrays, without (B, 3, 3) temporaries.

    Args:
        cov: The six distinct entries ``(c00, c01, c02, c11, c12, c22)`` of (B,) symmetric
            positive semi-definite matrices.

    Returns:
        (B, 3) eigenvalues in ascending order, clipped at 0, and (B, 3) unit eigenvectors of
        the smallest.
    """
    a00, a01, a02, a11, a12, a22 = cov
    q = (a00 + a11 + a22) / 3.0
    d0, d1, d2 = a00 - q, a11 - q, a22 - q
    off = a01 * a01 + a02 * a02 + a12 * a12
    p = np.sqrt((d0 * d0 + d1 * d1 + d2 * d2 + 2.0 * off) / 6.0)
    inv_p = 1.0 / np.where(p > 0, p, 1.0)
    b00, b11, b22 = d0 * inv_p, d1 * inv_p, d2 * inv_p
    b01, b02, b12 = a01 * inv_p, a02 * inv_p, a12 * inv_p
    det = (
        b00 * (b11 * b22 - b12 * b12)
        - b01 * (b01 * b22 - b12 * b02)
        + b02 * (b01 * b12 - b11 * b02)
    )
    phi = np.arccos(np.clip(det / 2.0, -1.0, 1.0)) / 3.0
    big = q + 2.0 * p * np.cos(phi)
    small = q + 2.0 * p * np.cos(phi + 2.0 * np.pi / 3.0)
    mid = 3.0 * q - big - small
    evals = np.clip(np.stack([small, mid, big], axis=1), 0.0, None)
    m00, m11, m22 = a00 - small, a11 - small, a22 - small
    crosses = np.stack(
        [
            # rows 0 x 1, 0 x 2 and 1 x 2 of cov - lambda_min I, each (B, 3)
            [a01 * a12 - a02 * m11, a02 * a01 - m00 * a12, m00 * m11 - a01 * a01],
            [a01 * m22 - a02 * a12, a02 * a02 - m00 * m22, m00 * a12 - a01 * a02],
            [m11 * m22 - a12 * a12, a12 * a02 - a01 * m22, a01 * a12 - m11 * a02],
        ]
    )  # (3 pairs, 3, B)
    sq = np.einsum("pcb,pcb->pb", crosses, crosses)  # (3 pairs, B) squared lengths
    best = np.argmax(sq, axis=0)
    rows = np.arange(len(a00))
    vec = crosses[best, :, rows]  # (B, 3)
    length = np.sqrt(sq[best, rows])
    scale = np.maximum((big - small) ** 2, np.finfo(float).tiny)
    weak = (length < _WEAK_CROSS * scale) | (mid - small <= _CLOSE_GAP * (big - small))
    vec /= np.where(length > 0, length, 1.0)[:, None]
    if weak.any():
        full = np.stack([a00, a01, a02, a01, a11, a12, a02, a12, a22], axis=1)[weak]
        w_vals, w_vecs = np.linalg.eigh(full.reshape(-1, 3, 3))
        evals[weak] = np.clip(w_vals, 0.0, None)
        vec[weak] = w_vecs[:, :, 0]
    return evals, vec


def _knn_pca(columns: np.ndarray, idx: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Smallest eigenpair of the covariance of each point's neighbourhood.

    Every neighbourhood is first shifted by its first member (the point itself), so the
    covariance ``E[d d^T] - E[d] E[d]^T`` of the shifted neighbours ``d``, which are only a
    neighbourhood's radius long, loses no precision to cancellation wherever the cloud lies.

    Args:
        columns: (3, M) the x, y and z coordinates of the finite points, each contiguous.
        idx: (B, k) indices into the points of each neighbourhood.

    Returns:
        (B, 3) eigenvalues in ascending order and (B, 3) unit normals (the eigenvector of the
        smallest eigenvalue).
    """
    k = idx.shape[1]
    shifted = []
    for axis in columns:
        g = axis[idx]  # (B, k)
        g -= g[:, :1]
        shifted.append(g)
    weights = np.full(k, 1.0 / k)
    means = [g @ weights for g in shifted]  # (B,) each; a matrix-vector product beats sum
    cov = tuple(
        np.einsum("ij,ij->i", shifted[a], shifted[b]) / k - means[a] * means[b] for a, b in _PAIRS
    )
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
    view = np.zeros(3) if viewpoint is None else as_float_array("viewpoint", viewpoint)
    check_shape("viewpoint", view, (3,))
    check_finite("viewpoint", view)
    good = pts[valid]
    if len(good) < k:
        raise InputError(
            f"points has {len(good)} valid (non-NaN) point(s), fewer than k={k}; give a larger "
            "cloud or a smaller k."
        )
    _, found = cKDTree(good).query(good, k=k)
    idx = np.asarray(found, dtype=np.int64).reshape(len(good), k)
    normals = np.empty((len(good), 3))
    curvature = np.empty(len(good))
    columns = np.ascontiguousarray(good.T)
    for start in range(0, len(good), _CHUNK):
        sl = slice(start, start + _CHUNK)
        evals, vecs = _knn_pca(columns, idx[sl])
        total = evals.sum(axis=1)
        curvature[sl] = np.where(total > 0, evals[:, 0] / np.where(total > 0, total, 1.0), 0.0)
        normals[sl] = vecs
    towards = view[None, :] - good
    flip = np.einsum("ij,ij->i", normals, towards) < 0
    normals[flip] *= -1.0
    if len(good) == len(pts):  # nothing dropped: the rows and indices are the cloud's own
        return Normals(normals=normals, curvature=curvature, neighbours=idx)
    out_n = np.full((len(pts), 3), np.nan)
    out_c = np.full(len(pts), np.nan)
    out_n[valid] = normals
    out_c[valid] = curvature
    rows = np.flatnonzero(valid)
    out_i = np.full((len(pts), k), -1, dtype=np.int64)
    out_i[valid] = rows[idx]
    return Normals(normals=out_n, curvature=out_c, neighbours=out_i)
