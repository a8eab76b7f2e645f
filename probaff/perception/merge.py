"""Multi-view merge of chapter 2 (Sec. 2.5): one set of segments from several classified views.

Each view is the classifier's output for one scan, already brought into one frame (the world
frame, metres): the centroid of each of its segments, its label vector (the six label
probabilities, columns in `LABELS` order) and its point count. Two segments of *different*
views are linked when

- their centroids lie closer than ``max_distance`` (default 0.05 m, the thesis's proximity
  threshold, Sec. 2.6.3), and
- their label vectors lie closer than ``max_label_distance`` in Euclidean distance (default
  0.7, the thesis's similarity threshold).

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

from probaff._checks import check_finite, check_positive, check_probability, check_shape
from probaff.errors import InputError
from probaff.perception.labels import LABELS

__all__ = ["MergedSegments", "merge_views"]

View = tuple[np.ndarray, np.ndarray, np.ndarray]


@dataclass(frozen=True, eq=False)
class MergedSegments:
    """Segments of several views, merged.

    Attributes:
        centroids: (M, 3) point-weighted centroid of each merged segment (world frame, m).
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


def _check_view(v: int, view: object) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    if not isinstance(view, Sequence) or len(view) != 3:
        raise InputError(
            f"views[{v}] must be a (centroids, label_vectors, point_counts) triple of arrays."
        )
    name = f"views[{v}]"
    try:
        centroids, labels, counts = (np.asarray(a, dtype=np.float64) for a in view)
    except (TypeError, ValueError):
        raise InputError(f"{name} must hold numeric arrays.") from None
    check_shape(f"{name} centroids", centroids, (None, 3))
    n = centroids.shape[0]
    check_shape(f"{name} label_vectors", labels, (n, len(LABELS)))
    check_shape(f"{name} point_counts", counts, (n,))
    check_finite(f"{name} centroids", centroids)
    check_probability(f"{name} label_vectors", labels)
    check_finite(f"{name} point_counts", counts)
    if np.any(counts <= 0) or np.any(counts != np.round(counts)):
        raise InputError(f"{name} point_counts must be positive integers (points per segment).")
    return (
        centroids.astype(np.float64),
        labels.astype(np.float64),
        counts.astype(np.int64),
    )


def merge_views(
    views: Sequence[View],
    *,
    max_distance: float = 0.05,
    max_label_distance: float = 0.7,
) -> MergedSegments:
    """Merge the classified segments of several views into one set.

    Args:
        views: One ``(centroids (S_v, 3), label_vectors (S_v, 6), point_counts (S_v,))``
            triple per view, centroids in the world frame (m). A view may hold no segments,
            but not all of them.
        max_distance: Centroids of linked segments lie closer than this (m, > 0).
        max_label_distance: Label vectors of linked segments lie closer than this (> 0).

    Returns:
        The `MergedSegments`, numbered in order of their first member (views in order, then
        segments in order).

    Raises:
        InputError: For no views, no segments in any view, a view that is not a triple, arrays
            of the wrong shapes, non-finite values, probabilities outside [0, 1], point counts
            that are not positive integers, or non-positive thresholds.
    """
    check_positive("max_distance", max_distance)
    check_positive("max_label_distance", max_label_distance)
    if isinstance(views, (str, bytes)) or not isinstance(views, Sequence) or not len(views):
        raise InputError("views is empty; give at least one (centroids, labels, counts) view.")
    checked = [_check_view(v, view) for v, view in enumerate(views)]
    sizes = [len(c) for c, _, _ in checked]
    total = sum(sizes)
    if total == 0:
        raise InputError("views hold no segments; give at least one segment in some view.")
    xyz = np.concatenate([c for c, _, _ in checked])
    labels = np.concatenate([lab for _, lab, _ in checked])
    counts = np.concatenate([n for _, _, n in checked])
    view_of = np.repeat(np.arange(len(checked)), sizes)

    pairs = cKDTree(xyz).query_pairs(r=float(max_distance), output_type="ndarray")
    if len(pairs):
        i, j = pairs[:, 0], pairs[:, 1]
        near = np.linalg.norm(xyz[i] - xyz[j], axis=1) < max_distance
        alike = np.linalg.norm(labels[i] - labels[j], axis=1) < max_label_distance
        keep = near & alike & (view_of[i] != view_of[j])
        i, j = i[keep], j[keep]
    else:
        i = j = np.zeros(0, dtype=np.int64)
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
