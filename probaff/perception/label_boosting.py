"""Calibrated gradient-boosted trees per affordance label: a higher-capacity `LabelClassifier`.

The thesis's logistic regressions draw one hyperplane per label through the segment
features, but the office's labels are rules of thresholds and conjunctions ("pushable forward
unless a neighbour lies within 0.15 m in front and overlaps it in height"), which trees split
on directly. `BoostedLabelClassifier` fits, per label in `LABELS`, scikit-learn's
`HistGradientBoostingClassifier` wrapped in `CalibratedClassifierCV` (its probabilities
recalibrated on held-out folds of the training set, so ``p >= 0.5`` keeps its meaning). A
label constant in training predicts that constant; a label with fewer positives (or
negatives) than calibration folds is fitted without calibration.

Options (`BoostingOptions`, our choices): 200 boosting rounds of at most 15 leaves at learning
rate 0.1, at least 10 segments per leaf and an L2 penalty of 1 (scikit-learn's defaults but
for the leaf size and the penalty, which regularise a few thousand segments), sigmoid (Platt)
calibration on 3 folds. Fits run on one thread: on a few thousand segments a thread pool
costs more than it saves.

Calibration (`BoostingOptions.calibration`): isotonic regression maps the trees' scores onto a
step function, so many segments share one probability and a threshold moves in steps; Platt's
sigmoid is smooth and monotone in the score. In the chapter 2 study (30 scenes, CV by scene,
all segments, ``"balanced"`` thresholds) sigmoid calibration scored mean precision / recall
85.21 / 86.51 % against isotonic's 84.57 / 87.43 with the study's folds (seed 0). Over the
folds of seeds 0-4 its precision was higher at every seed, 84.79 against 84.39 % on average,
for recall 86.59 against 87.24 %; it reached 85 % at seeds 0 and 3. On a single held-out
scene's centre view with 7 training scenes (the demo's size before it grew), the two tie:
72.5 / 77.7 against 72.4 / 79.3 % averaged over demo seeds 0-7.

Decision threshold (`BoostingOptions.threshold`): calibrated probabilities make ``p >= 0.5``
the most accurate decision, not the one that balances precision and recall; on the chapter 2
study's segments the trees at 0.5 reach recall well above precision (92.6 against 83.0 %).
With ``"balanced"`` (or ``"f1"``) `fit` chooses each label's threshold from the training data
alone: an inner cross-validation (``threshold_folds`` folds, grouped by scene when `fit` gets
``groups``, else by segment) gives out-of-fold calibrated probabilities of the training
segments, and the threshold is the one that maximises the smaller of their precision and
recall (or their F1 score); the model is then fitted on all the training segments and
`predict` applies the thresholds (`thresholds`). ``"fixed"`` keeps 0.5 and a number in
(0, 1) fixes every label's threshold; `predict_proba` stays calibrated whatever the option.
`best_threshold` is the rule; a label whose out-of-fold probabilities do not separate (a
constant label, one value) keeps 0.5.

The default, ``"balanced"`` on 3 inner folds, measured best in the chapter 2 study (30 scenes,
CV by scene, all segments, isotonic calibration: mean precision / recall 84.6 / 87.4 % against
83.0 / 92.6 at 0.5 and 81.5 / 94.4 with ``"f1"``; 5 inner folds with sigmoid calibration gave
85.14 / 87.12 against 3 folds' 85.21 / 86.51, for 5/3 of the fits): the study asks for
precision and recall both high, which ``min(P, R)`` scores directly, whereas F1's best
threshold is half the best F1 (below 0.5 here), which buys recall with precision. The inner CV
costs ``threshold_folds`` more fits. With very few training scenes (the demo's 7) the inner
folds are small and the thresholds noisy; ``"fixed"`` may then do better.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from sklearn.calibration import CalibratedClassifierCV
from sklearn.ensemble import HistGradientBoostingClassifier
from sklearn.model_selection import GroupKFold, KFold
from threadpoolctl import threadpool_limits

from probaff._checks import (
    as_bool_array,
    as_float_array,
    check_count,
    check_number,
    check_shape,
    real_number,
)
from probaff.errors import InputError, NotFittedError
from probaff.perception.labels import (
    check_segment_features,
    check_segment_labels,
    column_probabilities,
)

__all__ = ["THRESHOLD_RULES", "BoostedLabelClassifier", "BoostingOptions", "best_threshold"]

_CALIBRATIONS = ("isotonic", "sigmoid")

THRESHOLD_RULES: tuple[str, ...] = ("fixed", "f1", "balanced")
"""Named rules of `BoostingOptions.threshold`: 0.5; best F1; best min(precision, recall)."""


def _check_threshold(value: Any) -> str | float:
    """A rule of `THRESHOLD_RULES` or a number in (0, 1); `InputError` naming ``threshold``."""
    if isinstance(value, str) and value in THRESHOLD_RULES:
        return value
    number = real_number(value)  # NaN for anything but a real number
    if 0.0 < number < 1.0:
        return number
    raise InputError(
        f"threshold must be one of {', '.join(map(repr, THRESHOLD_RULES))} or a number in "
        f"(0, 1), got {value!r}; e.g. threshold='f1' or threshold=0.6."
    )


def best_threshold(truth: np.ndarray, probabilities: np.ndarray, rule: str = "f1") -> float:
    """The decision threshold of one label that scores best on held-out probabilities.

    The candidates are the midpoints between consecutive distinct values of `probabilities`
    (``p >= t`` then keeps exactly the values above the midpoint); each is scored by the F1
    score (``"f1"``) or the smaller of precision and recall (``"balanced"``) of ``p >= t``
    against `truth`, and ties go to the candidate nearest 0.5. With fewer than two distinct
    values, or no positive (or no negative) in `truth`, the threshold is 0.5.

    Args:
        truth: (N,) bool (or 0/1) labels.
        probabilities: (N,) out-of-fold probabilities of the label, finite.
        rule: ``"f1"`` or ``"balanced"``; ``"fixed"`` returns 0.5.

    Returns:
        The threshold, in (0, 1) for probabilities in [0, 1].

    Raises:
        InputError: For mismatched or empty inputs, non-finite probabilities, labels that
            are not 0/1, or an unknown `rule`.
    """
    if rule not in THRESHOLD_RULES:
        raise InputError(
            f"rule must be one of {', '.join(map(repr, THRESHOLD_RULES))}, got {rule!r}."
        )
    p = as_float_array("probabilities", probabilities)
    check_shape("probabilities", p, (None,))
    if p.size == 0 or not np.all(np.isfinite(p)):
        raise InputError("probabilities must be a non-empty (N,) array of finite numbers.")
    t = as_bool_array("truth", truth)
    check_shape("truth", t, (p.shape[0],))
    levels = np.unique(p)
    if rule == "fixed" or levels.size < 2 or t.all() or not t.any():
        return 0.5
    # predicting p >= levels[i] for i = 1..L-1: counts from the top down
    order = np.searchsorted(levels, p)
    positives = np.bincount(order, minlength=levels.size)[::-1].cumsum()[::-1]
    hits = np.bincount(order, weights=t.astype(np.float64), minlength=levels.size)
    hits = hits[::-1].cumsum()[::-1]
    precision = hits[1:] / positives[1:]
    recall = hits[1:] / t.sum()
    if rule == "f1":
        with np.errstate(invalid="ignore", divide="ignore"):
            score = np.where(hits[1:] > 0, 2 * hits[1:] / (positives[1:] + t.sum()), 0.0)
    else:
        score = np.minimum(precision, recall)
    candidates = 0.5 * (levels[1:] + levels[:-1])
    best = np.flatnonzero(score >= score.max() - 1e-12)
    return float(candidates[best[np.argmin(np.abs(candidates[best] - 0.5))]])


@dataclass(frozen=True)
class BoostingOptions:
    """Settings of `BoostedLabelClassifier` (see the module docstring for their sources).

    Attributes:
        max_iter: Boosting rounds per label (a positive integer).
        learning_rate: Shrinkage of each round (> 0).
        max_leaf_nodes: Leaves per tree (an integer >= 2).
        min_samples_leaf: Fewest segments in a leaf (a positive integer).
        l2_regularization: L2 penalty of the leaf values (>= 0).
        calibration: ``"sigmoid"`` (Platt scaling) or ``"isotonic"``, each on held-out
            folds of the training set.
        calibration_folds: Folds of the calibration (an integer >= 2).
        seed: Seed of the calibration folds, the threshold folds and the trees (an integer
            >= 0).
        threshold: Each label's decision threshold (`BoostedLabelClassifier.predict`): a
            rule of `THRESHOLD_RULES` chosen inside the training data (``"fixed"``: 0.5;
            ``"f1"``: best F1; ``"balanced"``: best min(precision, recall) of out-of-fold
            probabilities, see the module docstring), or a number in (0, 1) for every label.
        threshold_folds: Folds of the inner cross-validation that chooses the thresholds (an
            integer >= 2; fewer when the training data has fewer scenes).

    Raises:
        InputError: Naming the first field out of range or of the wrong type.
    """

    max_iter: int = 200
    learning_rate: float = 0.1
    max_leaf_nodes: int = 15
    min_samples_leaf: int = 10
    l2_regularization: float = 1.0
    calibration: str = "sigmoid"
    calibration_folds: int = 3
    seed: int = 0
    threshold: str | float = "balanced"
    threshold_folds: int = 3

    def __post_init__(self) -> None:
        object.__setattr__(self, "threshold", _check_threshold(self.threshold))
        object.__setattr__(
            self, "threshold_folds", check_count("threshold_folds", self.threshold_folds, minimum=2)
        )
        object.__setattr__(self, "max_iter", check_count("max_iter", self.max_iter))
        object.__setattr__(
            self, "max_leaf_nodes", check_count("max_leaf_nodes", self.max_leaf_nodes, minimum=2)
        )
        object.__setattr__(
            self, "min_samples_leaf", check_count("min_samples_leaf", self.min_samples_leaf)
        )
        object.__setattr__(
            self,
            "calibration_folds",
            check_count("calibration_folds", self.calibration_folds, minimum=2),
        )
        object.__setattr__(self, "seed", check_count("seed", self.seed, minimum=0))
        rate = check_number("learning_rate", self.learning_rate, bound="> 0")
        object.__setattr__(self, "learning_rate", rate)
        l2 = check_number("l2_regularization", self.l2_regularization, bound=">= 0")
        object.__setattr__(self, "l2_regularization", l2)
        if self.calibration not in _CALIBRATIONS:
            raise InputError(
                f"calibration must be one of {', '.join(_CALIBRATIONS)}, got {self.calibration!r}."
            )


class BoostedLabelClassifier:
    """Calibrated gradient-boosted trees, one per label in `LABELS`, with a threshold each.

    Args:
        options: The settings; `BoostingOptions()` when None.

    Raises:
        InputError: For options that are not `BoostingOptions`.

    Example:
        Six labels, each a threshold of one feature, on segments of 8 scenes: `fit` chooses
        each label's threshold by an inner CV that keeps every scene of its `groups` whole,
        then trains on all of them (30 boosting rounds, not the default 200, to be quick):

        >>> import numpy as np
        >>> from probaff.perception import BoostedLabelClassifier, BoostingOptions
        >>> rng = np.random.default_rng(0)
        >>> X = rng.normal(size=(800, 25))  # (segments, features)
        >>> Y = X[:, :6] > 0.5  # label k: feature k above 0.5
        >>> scenes = np.repeat(np.arange(8), 100)
        >>> model = BoostedLabelClassifier(BoostingOptions(max_iter=30))
        >>> model = model.fit(X[:600], Y[:600], groups=scenes[:600])  # scenes 0-5
        >>> model.predict_proba(X[600:]).shape, model.thresholds.shape
        ((200, 6), (6,))
        >>> bool((model.predict(X[600:]) == Y[600:]).mean() > 0.95)  # scenes 6 and 7
        True
    """

    def __init__(self, options: BoostingOptions | None = None) -> None:
        opt = BoostingOptions() if options is None else options
        if not isinstance(opt, BoostingOptions):
            raise InputError(f"options must be a BoostingOptions, got {type(opt).__name__}.")
        self.options = opt
        self._models: list[Any] | None = None
        self._width: int | None = None
        self._thresholds: np.ndarray | None = None

    @property
    def is_fitted(self) -> bool:
        """Whether `fit` has run."""
        return self._models is not None

    @property
    def thresholds(self) -> np.ndarray:
        """(6,) decision threshold of each label, `LABELS` order, chosen by `fit`.

        Raises:
            NotFittedError: Before `fit`.
        """
        if self._thresholds is None:
            raise NotFittedError("the classifier is not trained; call fit(X, Y) first.")
        return self._thresholds.copy()

    def _tree(self) -> HistGradientBoostingClassifier:
        o = self.options
        return HistGradientBoostingClassifier(
            max_iter=o.max_iter,
            learning_rate=o.learning_rate,
            max_leaf_nodes=o.max_leaf_nodes,
            min_samples_leaf=o.min_samples_leaf,
            l2_regularization=o.l2_regularization,
            early_stopping=False,
            random_state=o.seed,
        )

    def _fit_models(self, x: np.ndarray, y: np.ndarray) -> list[Any]:
        """One calibrated ensemble (or constant) per column of checked `y`, on one thread."""
        folds = self.options.calibration_folds
        models: list[Any] = []
        for k in range(y.shape[1]):
            column = y[:, k]
            positives = int(column.sum())
            if positives in (0, len(column)):
                models.append(float(column[0]))
            elif min(positives, len(column) - positives) < folds:
                models.append(self._tree().fit(x, column))
            else:
                model = CalibratedClassifierCV(
                    self._tree(), method=self.options.calibration, cv=folds
                )
                models.append(model.fit(x, column))
        return models

    def _inner_splits(self, n: int, groups: np.ndarray | None) -> list[tuple[Any, Any]]:
        """The inner folds that choose the thresholds: by scene when `groups` has two or more."""
        want, seed = self.options.threshold_folds, self.options.seed
        if groups is not None:
            n_groups = len(np.unique(groups))
            if n_groups >= 2:
                kfold = GroupKFold(n_splits=min(want, n_groups), shuffle=True, random_state=seed)
                return list(kfold.split(np.zeros(n), groups=groups))
        if n < 2:
            return []
        return list(KFold(n_splits=min(want, n), shuffle=True, random_state=seed).split(range(n)))

    def _choose_thresholds(
        self, x: np.ndarray, y: np.ndarray, groups: np.ndarray | None
    ) -> np.ndarray:
        """(6,) thresholds from out-of-fold probabilities of the training segments only."""
        rule = self.options.threshold
        if not isinstance(rule, str):
            return np.full(y.shape[1], rule)
        if rule == "fixed":
            return np.full(y.shape[1], 0.5)
        splits = self._inner_splits(len(x), groups)
        if not splits:
            return np.full(y.shape[1], 0.5)
        held_out = np.empty(y.shape)
        for train, test in splits:
            held_out[test] = column_probabilities(self._fit_models(x[train], y[train]), x[test])
        return np.array([best_threshold(y[:, k], held_out[:, k], rule) for k in range(y.shape[1])])

    def fit(
        self, X: np.ndarray, Y: np.ndarray, groups: np.ndarray | None = None
    ) -> BoostedLabelClassifier:
        """Choose each label's threshold on the training data, then train on all of it.

        Args:
            X: (S, D) segment features, finite.
            Y: (S, 6) bool (or 0/1) labels, columns in `LABELS` order.
            groups: (S,) scene of each segment, or None; the inner folds that choose the
                thresholds keep each scene whole when given (two scenes or more), else they
                split the segments.

        Returns:
            ``self``.

        Raises:
            InputError: For no segments, non-finite features, labels of the wrong shape or
                values, or `groups` of the wrong shape.
        """
        x = check_segment_features("X", X)
        y = check_segment_labels("Y", Y, x.shape[0])
        scenes = None
        if groups is not None:
            check_shape("groups", groups, (x.shape[0],))
            scenes = np.asarray(groups)
        with threadpool_limits(limits=1):
            thresholds = self._choose_thresholds(x, y, scenes)
            models = self._fit_models(x, y)
        self._models = models
        self._width = x.shape[1]
        self._thresholds = thresholds
        return self

    def predict_proba(self, X: np.ndarray) -> np.ndarray:
        """Calibrated label probabilities of segments (independent of the thresholds).

        The arguments, result and errors are those of
        `probaff.perception.labels.SegmentClassifier.predict_proba`.
        """
        if self._models is None:
            raise NotFittedError("the classifier is not trained; call fit(X, Y) first.")
        x = check_segment_features("X", X, self._width)
        with threadpool_limits(limits=1):
            return column_probabilities(self._models, x)

    def predict(self, X: np.ndarray) -> np.ndarray:
        """Label decisions of segments: ``predict_proba(X) >= thresholds``.

        Args:
            X: (S, D) segment features, D as in training.

        Returns:
            (S, 6) bool decision of each label, columns in `LABELS` order.

        Raises:
            NotFittedError: Before `fit`.
            InputError: For features of the wrong width, empty or non-finite.
        """
        return self.predict_proba(X) >= self.thresholds
