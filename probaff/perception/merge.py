"""Multi-view merge of chapter 2 (Sec. 2.5): one set of segments from several classified views.

Each view is the classifier's output for one scan, already brought into one common frame (the
world or robot frame, metres): for each of its segments the centroid, the label vector (the six
label probabilities, columns in `LABELS` order) and the point count, and, for the point
proximity, the segment's points. Two segments of *different* views are linked when

- they lie closer than ``max_distance`` (default 0.05 m, the thesis's proximity threshold,
  Sec. 2.6.3), and
- their label vectors lie closer than ``max_label_distance`` in Euclidean distance (default
  0.7, the thesis's similarity threshold).

How close two segments lie is read in one of two ways (``proximity``):

- ``"points"`` (the default): the smallest Euclidean distance between a point of one segment
  and a point of the other, i.e. the distance between the segments as point sets; 0 when they
  share a point, so overlapping surfaces seen from two views are close. It is computed exactly:
  pairs whose label vectors are too far apart are dropped first, then pairs whose axis-aligned
  bounding boxes lie ``max_distance`` or more apart (the gap between the boxes is a lower bound
  of the point distance); for each remaining pair the points of the smaller segment are queried
  for their nearest neighbour in a `scipy.spatial.cKDTree` of the larger segment's points (one
  tree per segment, built once, searches bounded by ``max_distance``). Every given point takes
  part (no subsampling).
- ``"centroid"``: the distance between the segments' centroids, the literal reading of the
  thesis's "Euclidean distances in XYZ space ... among segments".

Why points by default: measured on the chapter 2 study's 10 scanned office scenes (four views
per scene, 20 degrees apart, each scene's classifier trained on the other scenes; 1 / 2 / 4
views merged; ``results/point_cloud_labels/summary.md``):

============  ==================  ==================  ==================  ==================
proximity     completeness        purity              label accuracy      point-weighted
============  ==================  ==================  ==================  ==================
points        0.72 / 0.79 / 0.82  1.00 / 1.00 / 0.99  0.84 / 0.74 / 0.69  0.97 / 0.97 / 0.96
centroid      0.72 / 0.63 / 0.52  1.00 / 1.00 / 1.00  0.84 / 0.82 / 0.81  0.97 / 0.96 / 0.96
============  ==================  ==================  ==================  ==================

Two views of one surface cut it into segments of different extents, whose centroids lie far
more than 5 cm apart: with centroids almost nothing merges (80 merged segments from 4 views
against 22 from one), and completeness falls as views are added, against the purpose of the
merge. The thesis says such segments "should be close to each other (sometimes they might even
overlap)", which describes the segments' points. With the point distance completeness rises
with the views (26 merged segments from 4 views) at a purity still near 1. The label accuracy
per merged segment falls because the well-labelled surfaces seen in several views count once
instead of once per view, so the small segments seen once weigh more; the point-weighted
accuracy, and the accuracy of each view's segments under its merged label vector (0.80 either
way over 4 views), do not change. Merging the 4 views of one scene (about 260 000 segment
points) takes about 0.4 s with points.

Both comparisons are strict (``<``). Segments of one view are never linked directly (region
growing already separated them); they still join when both link to one segment of another view.
The connected components of the links (`scipy.sparse.csgraph.connected_components`) are the
merged segments; each gets the point-weighted mean centroid and label vector of its members and
the sum of their point counts.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from probaff._checks import (
    as_float_array,
    check_finite,
    check_positive,
    check_probability,
    check_shape,
)
from probaff.errors import InputError
from probaff.perception.labels import LABELS

__all__ = ["PROXIMITIES", "MergeView", "MergedSegments", "merge_views"]

PROXIMITIES = ("points", "centroid")
"""The readings of "segments lie close": nearest points (the default), or centroids."""


@dataclass(frozen=True, eq=False)
class MergeView:
    """One view's segments, as `merge_views` takes them; S segments, N points.

    Attributes:
        centroids: (S, 3) segment centroids (common frame, m).
        label_vectors: (S, 6) label probabilities, columns `LABELS`.
        point_counts: (S,) positive integers, points per segment (the merge's weights).
        points: (N, 3) the view's points (common frame, m), or None; needed by the
            ``"points"`` proximity. May hold points of no segment, and may be a subsample.
        point_segments: (N,) int each point's segment row in [0, S), or -1 for a point of no
            segment (as `probaff.perception.scan_labels.ViewSegments.point_segments`); given
            exactly when `points` is. Every segment needs at least one point.
    """

    centroids: np.ndarray
    label_vectors: np.ndarray
    point_counts: np.ndarray
    points: np.ndarray | None = None
    point_segments: np.ndarray | None = None


@dataclass(frozen=True, eq=False)
class MergedSegments:
    """Segments of several views, merged.

    Attributes:
        centroids: (M, 3) point-weighted centroid of each merged segment (common frame, m).
        label_vectors: (M, 6) point-weighted mean label vector.
        point_counts: (M,) int, total points.
        membership: One (S_v,) int array per view: the merged index of each of its segments.
    """

    centroids: np.ndarray
    label_vectors: np.ndarray
    point_counts: np.ndarray
    membership: tuple[np.ndarray, ...]

    @property
    def n_views(self) -> np.ndarray:
        """(M,) int: how many views contributed a segment to each merged segment."""
        seen = np.zeros((len(self.membership), len(self.point_counts)), dtype=bool)
        for v, merged in enumerate(self.membership):
            seen[v, merged] = True
        return seen.sum(axis=0)


@dataclass(frozen=True)
class _View:
    """A checked view: float centroids and labels, int counts, and per-segment point sets."""

    centroids: np.ndarray
    labels: np.ndarray
    counts: np.ndarray
    segment_points: tuple[np.ndarray, ...] | None  # S arrays (P_s, 3), or None


def _check_points(
    name: str, points: object, point_segments: object, n: int
) -> tuple[np.ndarray, ...]:
    """The (P_s, 3) points of each of the `n` segments, checked."""
    pts = as_float_array(f"{name} points", points)
    rows = as_float_array(f"{name} point_segments", point_segments)
    check_shape(f"{name} points", pts, (None, 3))
    check_shape(f"{name} point_segments", rows, (len(pts),))
    check_finite(f"{name} points", pts)
    if rows.size and (
        not np.issubdtype(rows.dtype, np.number)
        or not np.all(np.isfinite(rows))
        or np.any(rows != np.round(rows))
        or rows.min() < -1
        or rows.max() >= n
    ):
        raise InputError(
            f"{name} point_segments must hold each point's segment row in [0, {n}) (the view "
            "has that many segments) or -1 for a point of no segment."
        )
    rows = rows.astype(np.int64)
    on = rows >= 0
    sizes = np.bincount(rows[on], minlength=n)
    empty = np.flatnonzero(sizes == 0)
    if empty.size:
        raise InputError(
            f"{name} point_segments gives no point to segment(s) {empty[:5].tolist()} of its "
            f"{n}; every segment needs its points for the 'points' proximity."
        )
    if n == 0:
        return ()
    order = np.argsort(rows[on], kind="stable")
    return tuple(np.split(pts[on][order], np.cumsum(sizes)[:-1]))


def _check_view(v: int, view: object) -> _View:
    name = f"views[{v}]"
    if isinstance(view, MergeView):
        arrays: tuple[object, ...] = (view.centroids, view.label_vectors, view.point_counts)
        points, point_segments = view.points, view.point_segments
    elif isinstance(view, Sequence) and not isinstance(view, (str, bytes)) and len(view) == 3:
        arrays, points, point_segments = tuple(view), None, None
    else:
        raise InputError(
            f"{name} must be a MergeView or a (centroids, label_vectors, point_counts) triple "
            "of arrays."
        )
    centroids, labels, counts = (
        as_float_array(f"{name} {part}", a)
        for part, a in zip(("centroids", "label_vectors", "point_counts"), arrays, strict=True)
    )
    check_shape(f"{name} centroids", centroids, (None, 3))
    n = centroids.shape[0]
    check_shape(f"{name} label_vectors", labels, (n, len(LABELS)))
    check_shape(f"{name} point_counts", counts, (n,))
    check_finite(f"{name} centroids", centroids)
    check_probability(f"{name} label_vectors", labels)
    check_finite(f"{name} point_counts", counts)
    if np.any(counts <= 0) or np.any(counts != np.round(counts)):
        raise InputError(f"{name} point_counts must be positive integers (points per segment).")
    if (points is None) != (point_segments is None):
        raise InputError(
            f"{name} gives points without point_segments or the reverse; give both (each "
            "point's segment row) or neither."
        )
    segment_points = None
    if points is not None:
        segment_points = _check_points(name, points, point_segments, n)
    return _View(centroids, labels, counts.astype(np.int64), segment_points)


def _centroid_pairs(
    xyz: np.ndarray, labels: np.ndarray, view_of: np.ndarray, max_distance: float, max_label: float
) -> tuple[np.ndarray, np.ndarray]:
    """Linked (i, j) of the stacked segments by centroid distance and label distance."""
    pairs = cKDTree(xyz).query_pairs(r=max_distance, output_type="ndarray")
    if not len(pairs):
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    i, j = pairs[:, 0], pairs[:, 1]
    near = np.linalg.norm(xyz[i] - xyz[j], axis=1) < max_distance
    alike = np.linalg.norm(labels[i] - labels[j], axis=1) < max_label
    keep = near & alike & (view_of[i] != view_of[j])
    return i[keep], j[keep]


def _point_pairs(
    checked: list[_View], max_distance: float, max_label: float
) -> tuple[np.ndarray, np.ndarray]:
    """Linked (i, j) of the stacked segments by nearest-point distance and label distance."""
    sets = [p for view in checked for p in (view.segment_points or ())]
    labels = np.concatenate([view.labels for view in checked])
    view_of = np.repeat(np.arange(len(checked)), [len(view.counts) for view in checked])
    lo = np.array([p.min(axis=0) for p in sets]).reshape(-1, 3)
    hi = np.array([p.max(axis=0) for p in sets]).reshape(-1, 3)
    i, j = np.triu_indices(len(sets), k=1)
    gap = np.maximum(0.0, np.maximum(lo[j] - hi[i], lo[i] - hi[j]))
    candidate = (
        (view_of[i] != view_of[j])
        & (np.linalg.norm(labels[i] - labels[j], axis=1) < max_label)
        & (np.linalg.norm(gap, axis=1) < max_distance)
    )
    trees: dict[int, cKDTree] = {}
    linked = np.zeros(len(i), dtype=bool)
    for k in np.flatnonzero(candidate):
        small, large = (int(i[k]), int(j[k]))
        if len(sets[small]) > len(sets[large]):
            small, large = large, small
        if large not in trees:
            trees[large] = cKDTree(sets[large], balanced_tree=False, compact_nodes=False)
        # Only points within max_distance of the larger segment's box can lie that close.
        pts = sets[small]
        pts = pts[
            np.all(pts > lo[large] - max_distance, axis=1)
            & np.all(pts < hi[large] + max_distance, axis=1)
        ]
        if len(pts):
            d, _ = trees[large].query(pts, k=1, distance_upper_bound=max_distance)
            linked[k] = float(np.min(d)) < max_distance
    return i[linked], j[linked]


def merge_views(
    views: Sequence[MergeView | tuple[np.ndarray, np.ndarray, np.ndarray]],
    *,
    proximity: str = "points",
    max_distance: float = 0.05,
    max_label_distance: float = 0.7,
) -> MergedSegments:
    """Merge the classified segments of several views into one set.

    Args:
        views: One `MergeView` per view, in one common frame (m); a view may also be a
            ``(centroids (S_v, 3), label_vectors (S_v, 6), point_counts (S_v,))`` triple, which
            gives no points and serves the ``"centroid"`` proximity only. A view may hold no
            segments, but not all of them.
        proximity: How close two segments lie, one of `PROXIMITIES`: ``"points"`` (smallest
            distance between their points; every view needs ``points`` and
            ``point_segments``) or ``"centroid"`` (distance between their centroids). See the
            module docstring.
        max_distance: Linked segments lie closer than this (m, > 0).
        max_label_distance: Label vectors of linked segments lie closer than this (> 0).

    Returns:
        The `MergedSegments`, numbered in order of their first member (views in order, then
        segments in order).

    Raises:
        InputError: For no views, no segments in any view, a view that is neither a
            `MergeView` nor a triple, arrays of the wrong shapes, non-finite values,
            probabilities outside [0, 1], point counts that are not positive integers, point
            rows outside the view's segments or a segment without points, an unknown
            `proximity`, a view without points under ``"points"``, or non-positive thresholds.
    """
    if proximity not in PROXIMITIES:
        raise InputError(
            f"proximity must be one of {', '.join(map(repr, PROXIMITIES))}, got {proximity!r}."
        )
    check_positive("max_distance", max_distance)
    check_positive("max_label_distance", max_label_distance)
    if isinstance(views, (str, bytes)) or not isinstance(views, Sequence) or not len(views):
        raise InputError("views is empty; give at least one MergeView.")
    checked = [_check_view(v, view) for v, view in enumerate(views)]
    sizes = [len(view.counts) for view in checked]
    total = sum(sizes)
    if total == 0:
        raise InputError("views hold no segments; give at least one segment in some view.")
    if proximity == "points":
        missing = [v for v, view in enumerate(checked) if view.segment_points is None]
        if missing:
            raise InputError(
                f"views {missing} give no points; the 'points' proximity needs each view's "
                "points and point_segments (MergeView), or use proximity='centroid'."
            )
    xyz = np.concatenate([view.centroids for view in checked])
    labels = np.concatenate([view.labels for view in checked])
    counts = np.concatenate([view.counts for view in checked])
    view_of = np.repeat(np.arange(len(checked)), sizes)

    if proximity == "points":
        i, j = _point_pairs(checked, float(max_distance), float(max_label_distance))
    else:
        i, j = _centroid_pairs(xyz, labels, view_of, float(max_distance), float(max_label_distance))
    graph = coo_matrix((np.ones(len(i)), (i, j)), shape=(total, total))
    _, component = connected_components(graph, directed=False)
    # Renumber by first member so the numbering does not depend on scipy's order.
    _, first = np.unique(component, return_index=True)
    rank = np.empty(len(first), dtype=np.int64)
    rank[np.argsort(first, kind="stable")] = np.arange(len(first))
    merged = rank[component]

    n_merged = len(first)
    weight = counts.astype(np.float64)
    point_counts = np.bincount(merged, weights=weight, minlength=n_merged)
    centroids: np.ndarray = np.stack(
        [np.bincount(merged, weights=weight * xyz[:, d], minlength=n_merged) for d in range(3)],
        axis=1,
    )
    label_vectors: np.ndarray = np.stack(
        [
            np.bincount(merged, weights=weight * labels[:, k], minlength=n_merged)
            for k in range(len(LABELS))
        ],
        axis=1,
    )
    centroids = centroids / point_counts[:, None]
    label_vectors = np.clip(label_vectors / point_counts[:, None], 0.0, 1.0)
    bounds = np.cumsum([0, *sizes])
    return MergedSegments(
        centroids=centroids,
        label_vectors=label_vectors,
        point_counts=np.round(point_counts).astype(np.int64),
        membership=tuple(merged[bounds[v] : bounds[v + 1]] for v in range(len(checked))),
    )
