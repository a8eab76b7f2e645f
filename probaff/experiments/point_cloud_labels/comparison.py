"""The thesis's logistic regressions against the new model, and where the baseline errs.

`compare_models` cross-validates, by scene, on the stacked records of `scan_task`:

* ``thesis``: `LabelClassifier` (the thesis's logistic regressions) on the 25 features of the
  region-growing segments, the reproduction baseline;
* ``capacity``: `BoostedLabelClassifier` (calibrated gradient-boosted trees) on the same 25
  features;
* ``new``: `BoostedLabelClassifier` on the 25 features and the 23 context descriptors
  (`probaff.perception.segment_context`), the new model;
* ``whole_object``: `LabelClassifier` on the 25 features of the oracle segments (one per
  object and view, `object_segments`), its decision carried to every segment of that object.

The first three run on the segments of at least ``min_points`` points (0: all), with the same
folds (``n_splits`` folds grouped by scene, seed ``seed``, as `cross_validate_labels` deals
them); each tree model is fitted with its training folds' scenes, so that it chooses its
decision thresholds (`BoostingOptions.threshold`) on its training scenes only, and a test
segment's decision is its fold model's ``p >= threshold`` (the logistic regressions keep 0.5);
``whole_object`` runs on the oracle segments of the same scenes. The result gives
`scene_intervals` rows per model and the error breakdown (`attribute_errors`,
`cause_table`) of the baseline.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from sklearn.model_selection import GroupKFold

from probaff.affordance_labels import LABELS
from probaff.errors import InputError
from probaff.experiments.point_cloud_labels.causes import attribute_errors, cause_table
from probaff.experiments.point_cloud_labels.intervals import scene_intervals
from probaff.perception.label_boosting import BoostedLabelClassifier, BoostingOptions
from probaff.perception.labels import cross_validate_labels
from probaff.perception.segment_context import CONTEXT_NAMES

__all__ = ["MODELS", "ModelComparison", "compare_models", "stack_records"]

MODELS: tuple[str, ...] = ("thesis", "capacity", "new")
"""The models cross-validated on the region-growing segments, baseline first."""

_N_FEATURES, _N_CONTEXT = 25, len(CONTEXT_NAMES)


def stack_records(records: list[dict[str, Any]]) -> dict[str, np.ndarray]:
    """The segments of `scan_task` records, stacked, with their oracle segments.

    Args:
        records: Scene records of `scan_task` (each with ``context``, ``mixed``,
            ``fragment``, ``oracle_rows`` and ``oracle``).

    Returns:
        ``features`` (S, 25), ``context`` (S, 23), ``labels`` (S, 6) bool, ``groups`` (S,)
        scene index, ``point_counts``, ``mixed`` (S, 6) bool, ``fragment`` (S,) bool,
        ``oracle_rows`` (S,) row in the stacked oracle arrays or -1, and ``oracle_features``
        (G, 25), ``oracle_labels`` (G, 6), ``oracle_groups`` (G,).

    Raises:
        InputError: For no records, or records without the diagnostics (scanned by an older
            version: delete ``out/tasks`` and rerun).
    """
    if not records:
        raise InputError("records is empty; give the scene records of at least one scan.")
    missing = [r.get("index") for r in records if "oracle" not in r or "context" not in r]
    if missing:
        raise InputError(
            f"records of scenes {missing} lack the context descriptors or the oracle segments; "
            "delete the study's tasks folder and rerun to scan them again."
        )
    offsets = np.cumsum([0] + [len(r["oracle"]["object_ids"]) for r in records])
    rows = [
        np.where(np.asarray(r["oracle_rows"]) >= 0, np.asarray(r["oracle_rows"]) + offsets[i], -1)
        for i, r in enumerate(records)
    ]

    def cat(key: str, width: int | None = None, source: str | None = None) -> np.ndarray:
        parts = [(r[source] if source else r)[key] for r in records]
        if width is None:
            return np.concatenate([np.asarray(p) for p in parts])
        return np.concatenate([np.reshape(np.asarray(p, np.float64), (-1, width)) for p in parts])

    return {
        "features": cat("features", _N_FEATURES),
        "context": cat("context", _N_CONTEXT),
        "labels": cat("labels", len(LABELS)).astype(bool),
        "groups": np.concatenate([np.full(len(r["labels"]), r["index"]) for r in records]),
        "point_counts": cat("point_counts").astype(np.int64),
        "mixed": cat("mixed", len(LABELS)).astype(bool),
        "fragment": cat("fragment").astype(bool),
        "oracle_rows": np.concatenate(rows).astype(np.int64),
        "oracle_features": cat("features", _N_FEATURES, "oracle"),
        "oracle_labels": cat("labels", len(LABELS), "oracle").astype(bool),
        "oracle_groups": np.concatenate(
            [np.full(len(r["oracle"]["object_ids"]), r["index"]) for r in records]
        ),
    }


@dataclass(frozen=True, eq=False)
class ModelComparison:
    """The models' out-of-fold probabilities on S segments, their scores and the breakdown.

    Attributes:
        min_points: The least points of the segments compared (0: all).
        labels: (S, 6) bool ground truth of the segments compared.
        groups: (S,) their scenes.
        probabilities: Model name of `MODELS` -> (S, 6) out-of-fold probabilities.
        thresholds: Model name of `MODELS` -> (S, 6) decision threshold of each segment and
            label (its fold model's; 0.5 for the logistic regressions).
        whole_object: (S, 6) out-of-fold probabilities of each segment's whole object
            (baseline features and classifier on the oracle segments; the baseline's where
            the object has no oracle segment).
        scores: Model name -> `scene_intervals` rows.
        causes: (S, 6) int64 `attribute_errors` of the baseline.
        breakdown: `cause_table` rows.
    """

    min_points: int
    labels: np.ndarray
    groups: np.ndarray
    probabilities: dict[str, np.ndarray]
    thresholds: dict[str, np.ndarray]
    whole_object: np.ndarray
    scores: dict[str, list[dict[str, Any]]]
    causes: np.ndarray
    breakdown: list[dict[str, Any]]

    def decisions(self, model: str) -> np.ndarray:
        """(S, 6) bool out-of-fold decisions of `model` (a name of `MODELS`)."""
        return self.probabilities[model] >= self.thresholds[model]


def _cross_validate_trees(
    x: np.ndarray, y: np.ndarray, groups: np.ndarray, n_splits: int, seed: int, opt: BoostingOptions
) -> tuple[np.ndarray, np.ndarray]:
    """Out-of-fold probabilities and thresholds (each (S, 6)) of `BoostedLabelClassifier`.

    The folds are `cross_validate_labels`'s (whose run on the baseline checks the inputs
    first); each fold's model gets its training scenes, so it chooses its thresholds without
    the test fold.
    """
    probabilities = np.empty(y.shape)
    thresholds = np.empty(y.shape)
    kfold = GroupKFold(n_splits=n_splits, shuffle=True, random_state=seed)
    for train, test in kfold.split(x, groups=groups):
        model = BoostedLabelClassifier(opt).fit(x[train], y[train], groups[train])
        probabilities[test] = model.predict_proba(x[test])
        thresholds[test] = model.thresholds
    return probabilities, thresholds


def compare_models(
    data: dict[str, np.ndarray],
    *,
    n_splits: int,
    seed: int,
    min_points: int = 0,
    options: BoostingOptions | None = None,
    n_boot: int = 2000,
) -> ModelComparison:
    """Cross-validate the models of `MODELS` and break the baseline's errors down by cause.

    Args:
        data: `stack_records` of the scenes compared.
        n_splits: Folds of each CV by scene (>= 2, at most the scenes).
        seed: Seed of the folds, the trees and the bootstrap (an integer >= 0).
        min_points: Compare the segments of at least this many points only (0: all).
        options: The trees' settings; ``BoostingOptions(seed=seed)`` when None.
        n_boot: Scene bootstrap draws of the intervals.

    Returns:
        The `ModelComparison`.

    Raises:
        InputError: For no segment of ``min_points`` points, or any error of the CVs.
    """
    opt = BoostingOptions(seed=seed) if options is None else options
    keep = data["point_counts"] >= min_points
    if not keep.any():
        raise InputError(f"no segment has min_points={min_points} points; lower min_points.")
    y, groups = data["labels"][keep], data["groups"][keep]
    base = data["features"][keep]
    rich = np.hstack([base, data["context"][keep]])

    def cv(x: np.ndarray, labels: np.ndarray, scenes: np.ndarray) -> np.ndarray:
        return cross_validate_labels(x, labels, scenes, n_splits=n_splits, seed=seed).probabilities

    probabilities = {"thesis": cv(base, y, groups)}  # first: its CV checks the inputs
    thresholds = {"thesis": np.full(y.shape, 0.5)}
    for name, x in (("capacity", base), ("new", rich)):
        probabilities[name], thresholds[name] = _cross_validate_trees(
            x, y, groups, n_splits, seed, opt
        )
    oracle = cv(data["oracle_features"], data["oracle_labels"], data["oracle_groups"])
    rows = data["oracle_rows"][keep]
    whole = np.where((rows >= 0)[:, None], oracle[np.maximum(rows, 0)], probabilities["thesis"])
    baseline = probabilities["thesis"] >= 0.5
    causes = attribute_errors(
        y,
        baseline,
        mixed=data["mixed"][keep],
        fragment=data["fragment"][keep],
        whole_object=whole >= 0.5,
        capacity=probabilities["capacity"] >= thresholds["capacity"],
        features=probabilities["new"] >= thresholds["new"],
    )
    scores = {
        name: scene_intervals(y, p, groups, n_boot=n_boot, seed=seed, thresholds=thresholds[name])
        for name, p in probabilities.items()
    }
    scores["whole_object"] = scene_intervals(
        data["oracle_labels"], oracle, data["oracle_groups"], n_boot=n_boot, seed=seed
    )
    return ModelComparison(
        min_points=min_points,
        labels=y,
        groups=groups,
        probabilities=probabilities,
        thresholds=thresholds,
        whole_object=whole,
        scores=scores,
        causes=causes,
        breakdown=cause_table(y, baseline, causes),
    )
