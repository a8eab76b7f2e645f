"""Ground-truth segments of a scanned view and how far its region-growing segments miss them.

The error breakdown of the chapter 2 study (`probaff.experiments.point_cloud_labels.causes`)
needs, for each view of a scan:

* `object_segments`: the oracle segmentation, one segment per object seen (its returned
  points, in a segment or not), described by the same 25 features and 23 context descriptors
  as the region-growing segments and labelled by its object; objects with fewer than
  ``PerceptionConfig.min_size`` points are left out, as region growing leaves them out;
* `segment_diagnostics`: for each region-growing segment, whether it mixes objects whose value
  of a label differs (under-segmentation: more than ``mixed_share`` of its points on objects
  whose label disagrees with the segment's), whether it is a fragment of its object
  (over-segmentation: it holds less than ``fragment_share`` of the object's returned points in
  the view) and its object's row among the oracle segments.

Thresholds (our choices): ``mixed_share = 0.1`` (a tenth of a segment's points moves its
covariance and span features visibly) and ``fragment_share = 0.5`` (the segment is not the
object's main part). Robot frame (x forward, y left, z up), metres.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from probaff.affordance_labels import LABELS
from probaff.errors import InputError
from probaff.perception.scan_labels import PerceptionConfig, ViewSegments
from probaff.perception.segment_context import context_features
from probaff.perception.segment_features import segment_features
from probaff.sim.office import OfficeScene

__all__ = ["ObjectSegments", "SegmentDiagnostics", "object_segments", "segment_diagnostics"]


@dataclass(frozen=True, eq=False)
class ObjectSegments:
    """The oracle segments of one view, one per object seen; G segments.

    Attributes:
        features: (G, 25) `segment_features` columns (robot frame).
        context: (G, 23) `context_features` columns (robot frame).
        labels: (G, 6) bool labels of each object, `LABELS` order.
        object_ids: (G,) int64 object ids.
        point_counts: (G,) int64 returned points per object.
    """

    features: np.ndarray
    context: np.ndarray
    labels: np.ndarray
    object_ids: np.ndarray
    point_counts: np.ndarray


@dataclass(frozen=True, eq=False)
class SegmentDiagnostics:
    """How the S region-growing segments of one view relate to its objects.

    Attributes:
        mixed: (S, 6) bool, the segment mixes objects that disagree on the label.
        fragment: (S,) bool, the segment is a fragment of its majority object.
        oracle_rows: (S,) int64 the majority object's row in `ObjectSegments`, -1 if absent.
    """

    mixed: np.ndarray
    fragment: np.ndarray
    oracle_rows: np.ndarray


def _label_table(scene: OfficeScene, ids: np.ndarray) -> np.ndarray:
    """(len(ids), 6) bool labels of the objects `ids`."""
    return np.array([scene.label_of(int(i)) for i in ids], dtype=bool).reshape(-1, len(LABELS))


def object_segments(
    view: ViewSegments, scene: OfficeScene, config: PerceptionConfig
) -> ObjectSegments:
    """The oracle segmentation of `view`: one segment per object with enough points.

    Args:
        view: A scanned view (`scan_segments`).
        scene: Its office scene (the objects' labels).
        config: The pipeline's settings (``min_size``, ``neighbour_distance``).

    Returns:
        The `ObjectSegments` (objects kept in increasing id order).

    Raises:
        InputError: For a view, scene or config of the wrong type.
    """
    _check(view, scene, config)
    ids, inverse, counts = np.unique(view.point_object_ids, return_inverse=True, return_counts=True)
    big = counts >= config.min_size
    rows = np.where(big[inverse], inverse, -1)
    feats = segment_features(
        view.points,
        rows,
        neighbour_distance=config.neighbour_distance,
        viewpoint=view.viewpoint,
    )
    kept = feats.segment_ids
    renumber = np.full(len(ids), -1, dtype=np.int64)
    renumber[kept] = np.arange(len(kept))
    point_rows = np.where(rows >= 0, renumber[np.maximum(rows, 0)], -1)
    context = context_features(view.points, point_rows, len(kept))
    return ObjectSegments(
        features=feats.features,
        context=context,
        labels=_label_table(scene, ids[kept]),
        object_ids=ids[kept].astype(np.int64),
        point_counts=counts[kept].astype(np.int64),
    )


def segment_diagnostics(
    view: ViewSegments,
    scene: OfficeScene,
    oracle: ObjectSegments,
    *,
    mixed_share: float = 0.1,
    fragment_share: float = 0.5,
) -> SegmentDiagnostics:
    """Under- and over-segmentation of each region-growing segment of `view`.

    Args:
        view: A scanned view (`scan_segments`).
        scene: Its office scene (the objects' labels).
        oracle: The view's oracle segments (`object_segments`).
        mixed_share: Share of a segment's points on objects disagreeing with its label above
            which it counts as mixed for that label, in [0, 1).
        fragment_share: Share of its object's returned points below which a segment counts as
            a fragment, in (0, 1].

    Returns:
        The `SegmentDiagnostics`.

    Raises:
        InputError: For arguments of the wrong type or shares out of range.
    """
    _check(view, scene, PerceptionConfig())
    if not isinstance(oracle, ObjectSegments):
        raise InputError(f"oracle must be an ObjectSegments, got {type(oracle).__name__}.")
    if not 0.0 <= mixed_share < 1.0 or not 0.0 < fragment_share <= 1.0:
        raise InputError(
            f"mixed_share must lie in [0, 1) and fragment_share in (0, 1], got {mixed_share} "
            f"and {fragment_share}."
        )
    s = view.n_segments
    on = view.point_segments >= 0
    seg, pid = view.point_segments[on], view.point_object_ids[on]
    ids, inverse = np.unique(view.point_object_ids, return_inverse=True)
    point_labels = _label_table(scene, ids)[inverse[on]]  # (M, 6)
    disagree = point_labels != view.labels[seg]
    share = np.zeros((s, len(LABELS)))
    np.add.at(share, seg, disagree.astype(np.float64))
    counts = np.maximum(np.bincount(seg, minlength=s), 1)
    mixed = share / counts[:, None] > mixed_share
    own = np.bincount(seg[pid == view.object_ids[seg]], minlength=s)
    totals = dict(zip(ids.tolist(), np.bincount(inverse).tolist(), strict=True))
    whole = np.array([totals.get(int(o), 0) for o in view.object_ids], dtype=np.float64)
    fragment = own < fragment_share * np.maximum(whole, 1.0)
    where = {int(o): r for r, o in enumerate(oracle.object_ids)}
    rows = np.array([where.get(int(o), -1) for o in view.object_ids], dtype=np.int64)
    return SegmentDiagnostics(mixed=mixed, fragment=fragment, oracle_rows=rows)


def _check(view: object, scene: object, config: object) -> None:
    if not isinstance(view, ViewSegments):
        raise InputError(f"view must be a ViewSegments, got {type(view).__name__}.")
    if not isinstance(scene, OfficeScene):
        raise InputError(f"scene must be an OfficeScene, got {type(scene).__name__}.")
    if not isinstance(config, PerceptionConfig):
        raise InputError(f"config must be a PerceptionConfig, got {type(config).__name__}.")
