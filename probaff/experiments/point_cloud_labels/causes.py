"""Where the chapter 2 labelling errors come from: one cause per wrong (segment, label) pair.

A labelling error is a (segment, label) pair whose decision ``p >= 0.5`` of the baseline (the
thesis's logistic regressions on the 25 features of region-growing segments) differs from the
ground truth. `attribute_errors` gives each error the first of `CAUSES` that explains it:

1. ``under_segmentation``: the segment mixes objects that disagree on the label (more than a
   tenth of its points, `segment_diagnostics`), so no description of it can be right for all
   its points;
2. ``over_segmentation``: the segment is a fragment of its object, and the same features and
   classifier label the whole object (its oracle segment, `object_segments`) right;
3. ``classifier_capacity``: a classifier of more capacity (calibrated gradient-boosted trees)
   on the same features of the same segment gets it right;
4. ``features``: that classifier gets it right once the context descriptors
   (`probaff.perception.segment_context`) join the features;
5. ``label_rules``: the residual, which none of these fixes: the label follows from what the
   view does not show the segment's description (a neighbour out of view or occluded, a mass,
   the object's far side).

`cause_table` counts them per label, beside the baseline's confusion (true and false
positives and negatives), as the rows of the study's breakdown.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from probaff._checks import as_bool_array, check_shape
from probaff.affordance_labels import LABELS
from probaff.errors import InputError

__all__ = ["CAUSES", "attribute_errors", "cause_table"]

CAUSES: tuple[str, ...] = (
    "under_segmentation",
    "over_segmentation",
    "classifier_capacity",
    "features",
    "label_rules",
)
"""The causes, in the order they are tried."""


def _bool(name: str, x: Any, shape: tuple[int | None, ...]) -> np.ndarray:
    """`x` as a bool array of `shape`, or an `InputError` naming `name`."""
    arr = as_bool_array(name, x)
    check_shape(name, arr, shape)
    return arr


def attribute_errors(
    truth: np.ndarray,
    baseline: np.ndarray,
    *,
    mixed: np.ndarray,
    fragment: np.ndarray,
    whole_object: np.ndarray,
    capacity: np.ndarray,
    features: np.ndarray,
) -> np.ndarray:
    """The cause of each baseline error (module docstring), -1 where the baseline is right.

    Args:
        truth: (S, 6) bool ground-truth labels, `LABELS` order.
        baseline: (S, 6) bool decisions of the baseline.
        mixed: (S, 6) bool, the segment mixes objects disagreeing on the label.
        fragment: (S,) bool, the segment is a fragment of its object.
        whole_object: (S, 6) bool decisions of the baseline's features and classifier on the
            segment's whole object (the baseline's decisions where the object has no oracle
            segment).
        capacity: (S, 6) bool decisions of the higher-capacity classifier, same features.
        features: (S, 6) bool decisions of that classifier with the context descriptors.

    Returns:
        (S, 6) int64: -1 for a right decision, else the index of its cause in `CAUSES`.

    Raises:
        InputError: For arrays of other shapes or of values other than 0/1.
    """
    t = _bool("truth", truth, (None, len(LABELS)))
    shape = t.shape
    b = _bool("baseline", baseline, shape)
    steps = (
        _bool("mixed", mixed, shape),
        _bool("fragment", fragment, shape[:1])[:, None]
        & (_bool("whole_object", whole_object, shape) == t),
        _bool("capacity", capacity, shape) == t,
        _bool("features", features, shape) == t,
    )
    out = np.full(shape, -1, dtype=np.int64)
    left = b != t
    for cause, explains in enumerate(steps):
        hit = left & explains
        out[hit] = cause
        left &= ~hit
    out[left] = len(CAUSES) - 1
    return out


def cause_table(
    truth: np.ndarray, baseline: np.ndarray, causes: np.ndarray
) -> list[dict[str, Any]]:
    """Rows of the error breakdown: per label and over all labels.

    Args:
        truth: (S, 6) bool ground-truth labels.
        baseline: (S, 6) bool decisions of the baseline.
        causes: (S, 6) int64 from `attribute_errors`.

    Returns:
        One row per label of `LABELS` and one ``"all"`` row, with ``label``, ``segments``,
        the baseline's ``tp``, ``fp``, ``fn``, ``tn``, ``errors`` (``fp + fn``) and, per cause
        of `CAUSES`, the share of the errors it explains (percent; NaN without errors).

    Raises:
        InputError: For arrays of other shapes, or causes outside -1 .. 4.
    """
    t = _bool("truth", truth, (None, len(LABELS)))
    b = _bool("baseline", baseline, t.shape)
    check_shape("causes", causes, t.shape)
    c = np.asarray(causes)
    if c.dtype.kind not in "iu" or c.min(initial=0) < -1 or c.max(initial=0) >= len(CAUSES):
        raise InputError(f"causes must be integers in [-1, {len(CAUSES) - 1}] (attribute_errors).")
    if np.any((c >= 0) != (b != t)):
        raise InputError("causes must be -1 exactly where baseline equals truth.")
    rows = []
    for name, cols in [*((n, [k]) for k, n in enumerate(LABELS)), ("all", list(range(t.shape[1])))]:
        tt, bb, cc = t[:, cols], b[:, cols], c[:, cols]
        errors = int(np.count_nonzero(cc >= 0))
        row: dict[str, Any] = {
            "label": name,
            "segments": len(t),
            "tp": int(np.count_nonzero(tt & bb)),
            "fp": int(np.count_nonzero(~tt & bb)),
            "fn": int(np.count_nonzero(tt & ~bb)),
            "tn": int(np.count_nonzero(~tt & ~bb)),
            "errors": errors,
        }
        for k, cause in enumerate(CAUSES):
            row[f"{cause}_pct"] = (
                100.0 * np.count_nonzero(cc == k) / errors if errors else float("nan")
            )
        rows.append(row)
    return rows
