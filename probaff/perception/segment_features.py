"""The 25 geometric features of each point-cloud segment (chapter 2, Table 2.1).

Columns, in order:

* 0-2 saliency, from the eigenvalues ``lambda0 >= lambda1 >= lambda2`` of the segment's
  covariance ``(1/N) sum (X_i - X)(X_i - X)^T`` (raw, in m^2, as the thesis computes them):
  scatter ``lambda0``, linearity ``lambda0 - lambda1``, planarity ``lambda1 - lambda2``;
* 3-5 the normal: the unit eigenvector of ``lambda2``. Its sign points towards `viewpoint`
  when one is given (a camera sees the side of a surface that faces it). Without one the sign
  makes ``n_z >= 0``, except for near-vertical surfaces (``|n_z| < 0.1``, within about 5.7
  degrees of vertical; our choice, far above the tilt that sensor noise gives a wall's
  normal), whose normal points towards the robot's vertical axis (``n_xy . c_xy <= 0``);
* 6-8 span: the extent ``max - min`` of the segment along x, y and z (m);
* 9-11 centroid (x, y, z) (m);
* 12-23 pairwise occupancy: how many neighbouring segments lie in each of 12 directions. Two
  segments are neighbours when their shortest point-to-point distance is at most
  `neighbour_distance` (the thesis thresholds the shortest distance between segments). The
  direction of the centroid-to-centroid vector ``d = c_j - c_i`` is binned into 3 layers by
  its elevation ``atan2(d_z, |d_xy|)``: below (``< -elevation_deg``), level, above
  (``> elevation_deg``); and into 4 sectors by its azimuth ``atan2(d_y, d_x)``: front
  ``[-45, 45)`` degrees (+x), left ``[45, 135)`` (+y), back (``>= 135`` or ``< -135``), right
  ``[-135, -45)``. Columns run layer by layer (below, level, above), each front, left, back,
  right;
* 24 closeness: the shortest distances ``d_ij`` to the neighbours, scaled and normalised as
  ``(1 / |nbrs|) sum_j exp(-d_ij / closeness_scale)``, in (0, 1], 0 without neighbours.

Thresholds and defaults (the thesis gives no values; our choices):
    neighbour_distance = 0.15 m: a segment this close is in the way of a push (the thesis's
        rule "not pushable towards a neighbouring segment"). It must bridge the band of
        unassigned points that region growing leaves along every crease (about half a
        neighbourhood, 3 pixels, on each side); in noise-free 320 x 240 scans of the office
        scenes those gaps between touching surfaces (wall and floor, box and floor, table
        top and legs) measured 0.03-0.13 m.
    closeness_scale = 0.05 m: closeness then separates touching neighbours (about 0.03 m,
        ``exp(-0.6) ~ 0.55``) from those across a gap (0.15 m, ``exp(-3) ~ 0.05``).
    elevation_deg = asin(1/3) ~ 19.47 degrees: splits the sphere of directions into three
        layers of equal solid angle.
    Degenerate covariance: a segment with fewer than 3 points, or with
        ``lambda1 <= 1e-12 lambda0`` (collinear or coincident points, no normal), is skipped
        and counted.

Frames and units: points in the robot frame (x forward, y left, z up), metres. Points whose
label is -1 are ignored (they may be NaN).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike
from scipy.spatial import cKDTree

from probaff._checks import as_float_array, check_finite, check_positive, check_shape
from probaff.errors import InputError

__all__ = ["FEATURE_NAMES", "SegmentFeatures", "segment_features"]

_LAYERS = ("below", "level", "above")
_SECTORS = ("front", "left", "back", "right")

FEATURE_NAMES: tuple[str, ...] = (
    "scatter",
    "linearity",
    "planarity",
    "normal_x",
    "normal_y",
    "normal_z",
    "span_x",
    "span_y",
    "span_z",
    "centroid_x",
    "centroid_y",
    "centroid_z",
    *(f"occupancy_{layer}_{sector}" for layer in _LAYERS for sector in _SECTORS),
    "closeness",
)

_DEGENERATE = 1e-12  # lambda1 / lambda0 at or below which a segment has no defined normal
_VERTICAL_NZ = 0.1  # |n_z| below which a surface counts as vertical for the default sign


@dataclass(frozen=True)
class SegmentFeatures:
    """The feature table of a segmentation.

    Attributes:
        features: (S, 25) one row per kept segment, columns as `names`.
        segment_ids: (S,) the label of each row's segment, increasing.
        centroids: (S, 3) each segment's centroid in the robot frame (m).
        names: The 25 column names (`FEATURE_NAMES`).
        n_skipped: Segments skipped for fewer than 3 points or a degenerate covariance.
    """

    features: np.ndarray
    segment_ids: np.ndarray
    centroids: np.ndarray
    names: tuple[str, ...]
    n_skipped: int


def _validate(points: ArrayLike, labels: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """Return the labelled points and their labels, checked."""
    pts = as_float_array("points", points)
    check_shape("points", pts, (None, 3))
    if len(pts) == 0:
        raise InputError("points is an empty cloud; give the segmented (N, 3) points.")
    lab = np.asarray(labels)
    check_shape("labels", lab, (len(pts),))
    if not np.issubdtype(lab.dtype, np.integer):
        raise InputError(
            f"labels must be integer segment ids (-1 for none), got dtype {lab.dtype}; pass "
            "Segmentation.labels."
        )
    if lab.size and lab.min() < -1:
        raise InputError(f"labels must be >= -1 (-1 = unassigned), got {int(lab.min())}.")
    used = lab >= 0
    check_finite("points with a segment label", pts[used])
    return pts[used], lab[used].astype(np.int64)


def _saliency(
    pts: np.ndarray, starts: np.ndarray, counts: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Centroid, covariance eigenvalues and eigenvectors of each segment.

    Args:
        pts: (M, 3) points sorted by segment.
        starts: (S,) first row of each segment in `pts`.
        counts: (S,) points per segment.

    Returns:
        (S, 3) centroids, (S, 3) eigenvalues in descending order and (S, 3, 3) eigenvectors
        (columns, in the same order).
    """
    cent = np.add.reduceat(pts, starts, axis=0) / counts[:, None]
    seg = np.repeat(np.arange(len(starts)), counts)
    d = pts - cent[seg]
    outer = d[:, :, None] * d[:, None, :]
    cov = np.add.reduceat(outer, starts, axis=0) / counts[:, None, None]
    evals, evecs = np.linalg.eigh(cov)
    return cent, evals[:, ::-1], evecs[:, :, ::-1]


def _orient(normals: np.ndarray, cent: np.ndarray, viewpoint: np.ndarray | None) -> np.ndarray:
    """Fix the sign of each (S, 3) normal as the module docstring says."""
    if viewpoint is not None:
        flip = np.einsum("ij,ij->i", normals, viewpoint[None, :] - cent) < 0
    else:
        vertical = np.abs(normals[:, 2]) < _VERTICAL_NZ
        towards_axis = np.einsum("ij,ij->i", normals[:, :2], cent[:, :2]) > 0
        flip = np.where(vertical, towards_axis, normals[:, 2] < 0)
    out = normals.copy()
    out[flip] *= -1.0
    return out


_BY_X = 4096  # segments of more points, near at least `_BY_X_PAIRS` others, are sorted by x
_BY_X_PAIRS = 4  # once, so that each box cuts a slice of them


def _within(
    points: np.ndarray, lo: np.ndarray, hi: np.ndarray, limit: float, by_x: bool
) -> np.ndarray:
    """The points of (n, 3) `points` inside the box ``[lo - limit, hi + limit]``, as (m, 3).

    With `by_x`, `points` are sorted by x and only the slice of them in the box's x range is
    tested.
    """
    low, high = lo - limit, hi + limit
    if by_x:
        x = points[:, 0]
        points = points[np.searchsorted(x, low[0]) : np.searchsorted(x, high[0], side="right")]
    box = (points >= low) & (points <= high)
    return points[box[:, 0] & box[:, 1] & box[:, 2]]  # cheaper than all(axis=1) on 3 columns


_BATCH = 256  # query points per KD-tree call of `_nearest`, each bounded by the best so far


def _nearest(tree: cKDTree, query: np.ndarray, limit: float) -> float:
    """Shortest distance from the (n, 3) `query` points to those of `tree` below `limit`.

    The points are queried in batches of `_BATCH`, each bounded by the shortest distance found
    so far (one ulp above it, so no point at that distance is missed): a bound that tight
    prunes most of the tree. The result is the tree's distance of the closest pair, as one
    query of every point bounded by `limit` gives it.

    Returns:
        The shortest distance (m), ``inf`` when no pair lies closer than `limit`.
    """
    best = np.inf
    bound = limit
    for start in range(0, len(query), _BATCH):
        d, _ = tree.query(query[start : start + _BATCH], k=1, distance_upper_bound=bound)
        low = float(np.min(d))
        if low < best:
            best = low
            bound = float(np.nextafter(low, np.inf))
    return best


def _shortest_distances(
    groups: list[np.ndarray], lo: np.ndarray, hi: np.ndarray, limit: float
) -> np.ndarray:
    """Shortest point-to-point distance between every pair of segments, up to `limit`.

    Pairs whose bounding boxes lie further apart than `limit` are not searched. For the others,
    only points that can lie within `limit` of the other segment are searched: those of the
    smaller segment inside the larger one's box widened by `limit`, and those of the larger
    inside the box of the former widened by `limit` (a segment of more than `_BY_X` points near
    at least `_BY_X_PAIRS` others is sorted by x once, so each box cuts a slice of it). A KD-tree
    of the larger of these two sets is queried with the other (`_nearest`); the distances are
    the tree's, the same whichever side it holds.

    Args:
        groups: S arrays (n_s, 3) of each segment's points.
        lo: (S, 3) bounding-box minima.
        hi: (S, 3) bounding-box maxima.
        limit: Distances above this are reported as ``inf`` (m).

    Returns:
        (S, S) symmetric distances, ``inf`` beyond `limit` and on the diagonal.
    """
    s = len(groups)
    gap = np.maximum(
        0.0, np.maximum(lo[:, None, :] - hi[None, :, :], lo[None, :, :] - hi[:, None, :])
    )
    near = np.linalg.norm(gap, axis=2) <= limit
    dist = np.full((s, s), np.inf)
    np.fill_diagonal(near, False)
    by_x = [
        len(g) > _BY_X and n >= _BY_X_PAIRS for g, n in zip(groups, near.sum(axis=1), strict=True)
    ]
    ready = [
        g[np.argsort(g[:, 0], kind="stable")] if x else g for g, x in zip(groups, by_x, strict=True)
    ]
    for i, j in zip(*np.nonzero(np.triu(near, 1)), strict=True):
        a, b = (int(i), int(j)) if len(groups[i]) <= len(groups[j]) else (int(j), int(i))
        query = _within(ready[a], lo[b], hi[b], limit, by_x[a])
        if not len(query):
            continue
        found = _within(ready[b], query.min(axis=0), query.max(axis=0), limit, by_x[b])
        if not len(found):
            continue
        if len(found) < len(query):
            query, found = found, query
        best = _nearest(cKDTree(found), query, limit)
        if best <= limit:
            dist[a, b] = dist[b, a] = best
    return dist


def _occupancy(
    cent: np.ndarray, dist: np.ndarray, elevation_deg: float, scale: float
) -> np.ndarray:
    """The 12 occupancy bins and the closeness of each segment.

    Args:
        cent: (S, 3) centroids (m).
        dist: (S, S) shortest distances, ``inf`` for non-neighbours.
        elevation_deg: Elevation separating the level layer from below and above.
        scale: Closeness length scale (m).

    Returns:
        (S, 13): the 12 bin counts, then closeness.
    """
    s = len(cent)
    out = np.zeros((s, 13))
    i, j = np.nonzero(np.isfinite(dist))
    if i.size == 0:
        return out
    d = cent[j] - cent[i]
    elev = np.degrees(np.arctan2(d[:, 2], np.hypot(d[:, 0], d[:, 1])))
    layer = np.where(elev < -elevation_deg, 0, np.where(elev > elevation_deg, 2, 1))
    azim = np.degrees(np.arctan2(d[:, 1], d[:, 0]))
    sector = np.floor_divide(np.mod(azim + 45.0, 360.0), 90.0).astype(np.int64) % 4
    np.add.at(out, (i, layer * 4 + sector), 1.0)
    n_nbrs = np.bincount(i, minlength=s).astype(np.float64)
    close = np.bincount(i, weights=np.exp(-dist[i, j] / scale), minlength=s)
    out[:, 12] = np.where(n_nbrs > 0, close / np.maximum(n_nbrs, 1.0), 0.0)
    return out


def segment_features(
    points: ArrayLike,
    labels: ArrayLike,
    *,
    neighbour_distance: float = 0.15,
    closeness_scale: float = 0.05,
    elevation_deg: float = math.degrees(math.asin(1.0 / 3.0)),
    viewpoint: ArrayLike | None = None,
) -> SegmentFeatures:
    """Compute the 25 features of every segment of a labelled cloud.

    Args:
        points: (N, 3) points in the robot frame (m); rows labelled -1 are ignored.
        labels: (N,) integer segment ids, -1 for unassigned points.
        neighbour_distance: Largest shortest distance between two neighbouring segments (m).
        closeness_scale: Length scale of the closeness feature (m).
        elevation_deg: Elevation of the centroid direction that separates the level layer
            of occupancy bins from the below and above layers (degrees, in (0, 90)).
        viewpoint: Optional (3,) sensor position the normals point towards (m).

    Returns:
        `SegmentFeatures`: (S, 25) features, (S,) segment ids, (S, 3) centroids, the column
        names and the number of skipped segments.

    Raises:
        InputError: For an empty cloud, wrong shapes, non-integer labels, labels below -1,
            NaN or infinite labelled points, non-positive distances or an elevation outside
            (0, 90).
    """
    check_positive("neighbour_distance", neighbour_distance)
    check_positive("closeness_scale", closeness_scale)
    check_positive("elevation_deg", elevation_deg)
    if not float(elevation_deg) < 90.0:
        raise InputError(f"elevation_deg must lie in (0, 90) degrees, got {elevation_deg!r}.")
    view = None
    if viewpoint is not None:
        view = as_float_array("viewpoint", viewpoint)
        check_shape("viewpoint", view, (3,))
        check_finite("viewpoint", view)
    pts, lab = _validate(points, labels)
    empty = SegmentFeatures(
        features=np.zeros((0, len(FEATURE_NAMES))),
        segment_ids=np.zeros(0, dtype=np.int64),
        centroids=np.zeros((0, 3)),
        names=FEATURE_NAMES,
        n_skipped=0,
    )
    if lab.size == 0:
        return empty
    order = np.argsort(lab, kind="stable")
    pts, lab = pts[order], lab[order]
    ids, starts, counts = np.unique(lab, return_index=True, return_counts=True)
    big = counts >= 3
    n_small = int((~big).sum())
    keep_rows = np.repeat(big, counts)
    pts, lab = pts[keep_rows], lab[keep_rows]
    ids, counts = ids[big], counts[big]
    if ids.size == 0:
        return SegmentFeatures(
            empty.features, empty.segment_ids, empty.centroids, FEATURE_NAMES, n_small
        )
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    cent, evals, evecs = _saliency(pts, starts, counts)
    ok = (evals[:, 0] > 0) & (evals[:, 1] > _DEGENERATE * evals[:, 0])
    groups = [pts[a : a + c] for a, c in zip(starts[ok], counts[ok], strict=True)]
    lo = np.minimum.reduceat(pts, starts, axis=0)[ok]
    hi = np.maximum.reduceat(pts, starts, axis=0)[ok]
    cent, evals, evecs = cent[ok], evals[ok], evecs[ok]
    normals = _orient(evecs[:, :, 2], cent, view)
    dist = _shortest_distances(groups, lo, hi, float(neighbour_distance))
    occupancy = _occupancy(cent, dist, float(elevation_deg), float(closeness_scale))
    saliency = np.stack([evals[:, 0], evals[:, 0] - evals[:, 1], evals[:, 1] - evals[:, 2]], axis=1)
    features = np.concatenate([saliency, normals, hi - lo, cent, occupancy], axis=1)
    return SegmentFeatures(
        features=features,
        segment_ids=ids[ok],
        centroids=cent,
        names=FEATURE_NAMES,
        n_skipped=n_small + int((~ok).sum()),
    )
