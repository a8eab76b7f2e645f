"""The six affordance labels of chapter 2 and one logistic regression per label.

A segment of an office scene (region growing over its point cloud) is described by a feature
row, ``features (S, D)``; chapter 2 uses D = 25 geometric features. Each of the six binary
labels in `LABELS` (pushable forward / backward / left / right in the robot frame, x forward
and z up; liftable; graspable) gets its own logistic regression, ``p_l(x) = sigma(theta_l0 +
sum_i theta_li x_i)``, behind a `StandardScaler`, as in the thesis (which trained them with
WEKA's logistic regression).

`cross_validate_labels` measures the classifiers with K-fold cross-validation grouped by scene
(no scene in both the training and the test folds of a split; the thesis used 4 folds over 195
segments from 10 scenes). The metrics pool the out-of-fold probabilities of all folds, as
WEKA's cross-validation does:

- precision and recall of the decision ``p >= 0.5`` (the natural threshold of a logistic
  regression), NaN where undefined (no predicted positive for precision, no true positive for
  recall);
- average precision and ROC AUC of the probabilities, NaN where a label is constant over all
  segments; `LabelCVResult.fold_roc_auc` holds each test fold's AUC, NaN where that fold's
  labels are constant;
- a reliability diagram per label (`reliability`, 10 equal-width bins on [0, 1] by default).

Thresholds and their source: the decision threshold 0.5 (our choice, the logistic
regression's own), the regularisation ``C = 1`` (scikit-learn's default; the thesis does not
give WEKA's ridge), ``max_iter = 2000`` (our choice, ample for standardised features), and the
thesis's results in `THESIS_PR` (Table 2.2, percent). Fits run on one BLAS thread: on a few
hundred segments, waking a thread pool costs more than the solver.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from types import MappingProxyType
from typing import Any, NamedTuple, Protocol

import numpy as np
from sklearn.linear_model import LogisticRegression
from sklearn.metrics import average_precision_score, roc_auc_score
from sklearn.model_selection import GroupKFold
from sklearn.pipeline import Pipeline, make_pipeline
from sklearn.preprocessing import StandardScaler
from threadpoolctl import threadpool_limits

from probaff._checks import (
    as_bool_array,
    as_float_array,
    check_count,
    check_finite,
    check_positive,
    check_probability,
    check_shape,
)
from probaff.affordance_labels import LABELS, label_index
from probaff.errors import InputError, NotFittedError

__all__ = [
    "LABELS",
    "THESIS_PR",
    "LabelCVResult",
    "LabelClassifier",
    "PerColumnLogistic",
    "Reliability",
    "SegmentClassifier",
    "check_segment_features",
    "check_segment_labels",
    "column_probabilities",
    "cross_validate_labels",
    "label_index",
    "reliability",
]


THESIS_PR = MappingProxyType(
    {
        "push_forward": (82.0, 81.0),
        "push_backward": (82.4, 81.9),
        "push_left": (82.4, 81.9),
        "push_right": (78.0, 78.5),
        "liftable": (78.9, 80.4),
        "graspable": (86.8, 86.7),
        "average": (81.8, 81.7),
    }
)
"""Thesis Table 2.2: ``label -> (precision, recall)`` in percent, plus ``"average"``."""


class SegmentClassifier(Protocol):
    """What `cross_validate_labels` trains: ``fit(X, Y)`` then ``predict_proba(X)`` (S, 6)."""

    def fit(self, X: np.ndarray, Y: np.ndarray) -> Any:
        """Train on (S, D) features and (S, 6) bool labels."""

    def predict_proba(self, X: np.ndarray) -> np.ndarray:
        """Label probabilities of segments.

        Args:
            X: (S, D) segment features, D as in training.

        Returns:
            (S, 6) probability of each label, columns in `LABELS` order.

        Raises:
            NotFittedError: Before `fit`.
            InputError: For features of the wrong width, empty or non-finite.
        """


def check_segment_features(name: str, x: Any, width: int | None = None) -> np.ndarray:
    """Segment features `(S, D)` as floats, `D` = `width` when given.

    Raises:
        InputError: Naming `name`, when empty, of the wrong shape or non-finite.
    """
    arr = as_float_array(name, x)
    check_shape(name, arr, (None, width))
    if arr.shape[0] == 0 or arr.shape[1] == 0:
        raise InputError(f"{name} is empty (shape {arr.shape}); give at least one segment.")
    check_finite(name, arr)
    return arr


def check_segment_labels(name: str, y: Any, n: int) -> np.ndarray:
    """Labels `(n, len(LABELS))` as bools.

    Raises:
        InputError: Naming `name`, for another shape or values other than 0 and 1.
    """
    arr = as_bool_array(name, y)
    check_shape(name, arr, (n, len(LABELS)))
    return arr


def column_probabilities(models: Sequence[Any], x: np.ndarray) -> np.ndarray:
    """Probability of each column at checked features, from one fitted model per column.

    Args:
        models: `K` binary classifiers with ``predict_proba``, or a float each for a column
            that was constant in training (that constant, 0.0 or 1.0, for every row).
        x: (N, D) checked features.

    Returns:
        (N, K) probability that each column is true.
    """
    out = np.empty((x.shape[0], len(models)))
    for k, model in enumerate(models):
        out[:, k] = model if isinstance(model, float) else model.predict_proba(x)[:, 1]
    return out


class PerColumnLogistic:
    """One standardised logistic regression per column of a bool target, over feature rows.

    The common part of the per-label (`LabelClassifier`) and per-direction
    (`probaff.planning.manipulation.AffordanceClassifier`) classifiers; a subclass checks its
    inputs and names its columns. A column that is constant in training needs no regression:
    it predicts that constant (0 or 1) for every row, so no solver runs and no warning is
    raised.

    Args:
        C: Inverse L2 regularisation strength of each logistic regression (> 0).
        max_iter: Iteration limit of the solver (a positive integer).

    Raises:
        InputError: For a non-positive `C` or a `max_iter` that is not a positive integer.
    """

    C_NAME = "C"
    """How the error for a bad `C` names it."""

    def __init__(self, C: float = 1.0, max_iter: int = 2000) -> None:
        check_positive(self.C_NAME, C)
        self.C = float(C)
        self.max_iter = check_count("max_iter", max_iter)
        self._models: list[Pipeline | float] | None = None
        self._width: int | None = None

    @property
    def is_fitted(self) -> bool:
        """Whether `fit` has run."""
        return self._models is not None

    def _fit_columns(self, x: np.ndarray, y: np.ndarray) -> None:
        """Fit one regression per column of checked targets `y` (N, K) bool on `x` (N, D)."""
        models: list[Pipeline | float] = []
        for k in range(y.shape[1]):
            column = y[:, k]
            if column.all() or not column.any():
                models.append(float(column[0]))
                continue
            model = make_pipeline(
                StandardScaler(), LogisticRegression(C=self.C, max_iter=self.max_iter)
            )
            models.append(model.fit(x, column))
        self._models = models
        self._width = x.shape[1]

    def _predict_columns(self, x: np.ndarray) -> np.ndarray:
        """(N, K) probability of each column at checked features `x` (N, D)."""
        if self._models is None:
            raise NotFittedError("the classifier is not trained; call fit first.")
        return column_probabilities(self._models, x)


class LabelClassifier(PerColumnLogistic):
    """One standardised logistic regression per label in `LABELS`.

    A label whose training column is constant needs no regression: it predicts that constant
    (0 or 1) for every segment, so no solver runs and no warning is raised.

    Args:
        C: Inverse L2 regularisation strength of each logistic regression (> 0).
        max_iter: Iteration limit of the solver (a positive integer).

    Raises:
        InputError: For a non-positive `C` or a `max_iter` that is not a positive integer.
    """

    def fit(self, X: np.ndarray, Y: np.ndarray) -> LabelClassifier:
        """Train the six regressions.

        Args:
            X: (S, D) segment features, finite.
            Y: (S, 6) bool (or 0/1) ground-truth labels, columns in `LABELS` order.

        Returns:
            ``self``.

        Raises:
            InputError: For no segments, non-finite features, or labels of the wrong shape or
                values.
        """
        x = check_segment_features("X", X)
        y = check_segment_labels("Y", Y, x.shape[0])
        with threadpool_limits(limits=1):
            self._fit_columns(x, y)
        return self

    def predict_proba(self, X: np.ndarray) -> np.ndarray:
        """Label probabilities of segments.

        The arguments, result and errors are those of `SegmentClassifier.predict_proba`.
        """
        if self._models is None:
            raise NotFittedError("the classifier is not trained; call fit(X, Y) first.")
        return self._predict_columns(check_segment_features("X", X, self._width))


class Reliability(NamedTuple):
    """A reliability diagram of one label; unpacks as ``(centres, frequency, counts)``.

    Attributes:
        centres: (B,) bin centres on [0, 1].
        frequency: (B,) observed share of positives per bin, NaN in an empty bin.
        counts: (B,) int, how many predictions fell in each bin.
    """

    centres: np.ndarray
    frequency: np.ndarray
    counts: np.ndarray


def reliability(p: np.ndarray, y: np.ndarray, n_bins: int = 10) -> Reliability:
    """Reliability diagram: observed frequency of positives per bin of predicted probability.

    Bins are `n_bins` equal-width intervals ``[k / B, (k + 1) / B)`` of [0, 1], the last one
    closed so that ``p = 1`` counts. A calibrated predictor's frequencies lie on the diagonal
    (``frequency ~= centres``) within binomial sampling error.

    Args:
        p: (N,) predicted probabilities in [0, 1].
        y: (N,) bool (or 0/1) outcomes.
        n_bins: Number of bins (a positive integer).

    Returns:
        A `Reliability` with ``(centres, frequency, counts)``, each of shape (n_bins,); it
        unpacks as that tuple.

    Raises:
        InputError: For empty or mismatched inputs, probabilities outside [0, 1], outcomes that
            are not 0/1, or a bad `n_bins`.
    """
    bins = check_count("n_bins", n_bins)
    probs = as_float_array("p", p)
    check_shape("p", probs, (None,))
    if probs.size == 0:
        raise InputError("p is empty; give at least one predicted probability.")
    check_probability("p", probs)
    check_shape("y", y, (probs.shape[0],))
    outcomes = np.asarray(y)
    check_finite("y", outcomes)
    if not np.all((outcomes == 0) | (outcomes == 1)):
        raise InputError("y must be bool or 0/1 outcomes.")
    index = np.minimum((probs * bins).astype(np.int64), bins - 1)
    counts = np.bincount(index, minlength=bins)
    positives = np.bincount(index, weights=outcomes.astype(np.float64), minlength=bins)
    with np.errstate(invalid="ignore", divide="ignore"):
        frequency = np.where(counts > 0, positives / np.maximum(counts, 1), np.nan)
    centres = (np.arange(bins) + 0.5) / bins
    return Reliability(centres=centres, frequency=frequency, counts=counts)


@dataclass(frozen=True, eq=False)
class LabelCVResult:
    """Grouped cross-validation of the six label classifiers.

    Attributes:
        probabilities: (S, 6) out-of-fold probability of each label.
        folds: (S,) int, the test fold of each segment.
        precision: (6,) precision of ``p >= 0.5``, pooled over folds; NaN with no predicted
            positive.
        recall: (6,) recall of ``p >= 0.5``, pooled; NaN with no true positive.
        average_precision: (6,) pooled average precision; NaN for a constant label.
        roc_auc: (6,) pooled ROC AUC; NaN for a constant label.
        fold_roc_auc: (n_splits, 6) ROC AUC of each test fold; NaN where that fold's labels
            are constant.
        reliability: One `Reliability` per label, in `LABELS` order, of the pooled
            probabilities.
    """

    probabilities: np.ndarray
    folds: np.ndarray
    precision: np.ndarray
    recall: np.ndarray
    average_precision: np.ndarray
    roc_auc: np.ndarray
    fold_roc_auc: np.ndarray
    reliability: tuple[Reliability, ...]

    @property
    def mean_precision(self) -> float:
        """Mean precision over the labels where it is defined (NaN if none)."""
        return _nanmean(self.precision)

    @property
    def mean_recall(self) -> float:
        """Mean recall over the labels where it is defined (NaN if none)."""
        return _nanmean(self.recall)


def _nanmean(values: np.ndarray) -> float:
    finite = values[np.isfinite(values)]
    return float(finite.mean()) if finite.size else float("nan")


def _ranking_scores(truth: np.ndarray, prob: np.ndarray) -> tuple[float, float]:
    """(average precision, ROC AUC) of one label; NaN for constant `truth`."""
    if truth.all() or not truth.any():
        return float("nan"), float("nan")
    return float(average_precision_score(truth, prob)), float(roc_auc_score(truth, prob))


def _precision_recall(truth: np.ndarray, predicted: np.ndarray) -> tuple[float, float]:
    hits = float(np.count_nonzero(truth & predicted))
    n_pred = np.count_nonzero(predicted)
    n_true = np.count_nonzero(truth)
    precision = hits / n_pred if n_pred else float("nan")
    recall = hits / n_true if n_true else float("nan")
    return precision, recall


def cross_validate_labels(
    X: np.ndarray,
    Y: np.ndarray,
    groups: np.ndarray,
    *,
    n_splits: int = 4,
    seed: int = 0,
    C: float = 1.0,
    n_bins: int = 10,
    classifier: Callable[[], SegmentClassifier] | None = None,
) -> LabelCVResult:
    """K-fold cross-validation of `LabelClassifier` (or another classifier), grouped by scene.

    Scenes are shuffled with `seed` and dealt into `n_splits` folds of near-equal segment
    counts (scikit-learn's `GroupKFold`), so no scene is in both the training and the test
    folds of a split. A label constant in a training fold predicts that constant.

    Args:
        X: (S, D) segment features.
        Y: (S, 6) bool ground-truth labels, columns in `LABELS` order.
        groups: (S,) scene id of each segment (any sortable values).
        n_splits: Number of folds, an integer >= 2 and <= the number of scenes.
        seed: Seed of the scene shuffle.
        C: Inverse regularisation strength of each regression.
        n_bins: Bins of each reliability diagram.
        classifier: Builds a fresh untrained classifier for each fold (e.g.
            `probaff.perception.label_boosting.BoostedLabelClassifier`); None trains
            ``LabelClassifier(C=C)``, the thesis's logistic regressions.

    Returns:
        A `LabelCVResult`.

    Raises:
        InputError: For bad shapes, no segments, non-finite features, labels that are not 0/1,
            `n_splits` outside [2, number of scenes], or a `classifier` that is not callable.
    """
    x = check_segment_features("X", X)
    y = check_segment_labels("Y", Y, x.shape[0])
    check_shape("groups", groups, (x.shape[0],))
    scene = np.asarray(groups)
    if scene.dtype.kind == "f":
        check_finite("groups", scene)
    try:
        n_scenes = len(np.unique(scene))
    except TypeError:
        raise InputError("groups must hold scene ids of one sortable type.") from None
    splits = check_count("n_splits", n_splits, minimum=2)
    bins = check_count("n_bins", n_bins)
    if classifier is not None and not callable(classifier):
        raise InputError(
            f"classifier must build an untrained classifier when called, got "
            f"{type(classifier).__name__}; pass e.g. BoostedLabelClassifier, not an instance."
        )
    check_positive("C", C)
    make: Callable[[], SegmentClassifier] = (
        classifier if classifier is not None else lambda: LabelClassifier(C=C)
    )
    seed = check_count("seed", seed, minimum=0)
    if splits > n_scenes:
        raise InputError(
            f"n_splits={splits} exceeds the {n_scenes} scene(s) in groups; use n_splits <= "
            f"{n_scenes} or add scenes."
        )
    probabilities = np.empty((x.shape[0], len(LABELS)))
    folds = np.empty(x.shape[0], dtype=np.int64)
    fold_auc = np.full((splits, len(LABELS)), np.nan)
    kfold = GroupKFold(n_splits=splits, shuffle=True, random_state=seed)
    for fold, (train, test) in enumerate(kfold.split(x, groups=scene)):
        model = make()
        model.fit(x[train], y[train])
        probabilities[test] = model.predict_proba(x[test])
        folds[test] = fold
        for k in range(len(LABELS)):
            fold_auc[fold, k] = _ranking_scores(y[test, k], probabilities[test, k])[1]
    predicted = probabilities >= 0.5
    pr = np.array([_precision_recall(y[:, k], predicted[:, k]) for k in range(len(LABELS))])
    ranking = np.array([_ranking_scores(y[:, k], probabilities[:, k]) for k in range(len(LABELS))])
    return LabelCVResult(
        probabilities=probabilities,
        folds=folds,
        precision=pr[:, 0],
        recall=pr[:, 1],
        average_precision=ranking[:, 0],
        roc_auc=ranking[:, 1],
        fold_roc_auc=fold_auc,
        reliability=tuple(
            reliability(probabilities[:, k], y[:, k], n_bins=bins) for k in range(len(LABELS))
        ),
    )
