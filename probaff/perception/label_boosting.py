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
for the leaf size and the penalty, which regularise a few thousand segments), isotonic
calibration on 3 folds (isotonic: trees' scores are not sigmoid-shaped). Fits run on one
thread: on a few thousand segments a thread pool costs more than it saves.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from sklearn.calibration import CalibratedClassifierCV
from sklearn.ensemble import HistGradientBoostingClassifier
from threadpoolctl import threadpool_limits

from probaff._checks import check_count, check_number
from probaff.errors import InputError, NotFittedError
from probaff.perception.labels import check_segment_features, check_segment_labels

__all__ = ["BoostedLabelClassifier", "BoostingOptions"]

_CALIBRATIONS = ("isotonic", "sigmoid")


@dataclass(frozen=True)
class BoostingOptions:
    """Settings of `BoostedLabelClassifier` (see the module docstring for their sources).

    Attributes:
        max_iter: Boosting rounds per label (a positive integer).
        learning_rate: Shrinkage of each round (> 0).
        max_leaf_nodes: Leaves per tree (an integer >= 2).
        min_samples_leaf: Fewest segments in a leaf (a positive integer).
        l2_regularization: L2 penalty of the leaf values (>= 0).
        calibration: ``"isotonic"`` or ``"sigmoid"``.
        calibration_folds: Folds of the calibration (an integer >= 2).
        seed: Seed of the calibration folds and the trees (an integer >= 0).

    Raises:
        InputError: Naming the first field out of range or of the wrong type.
    """

    max_iter: int = 200
    learning_rate: float = 0.1
    max_leaf_nodes: int = 15
    min_samples_leaf: int = 10
    l2_regularization: float = 1.0
    calibration: str = "isotonic"
    calibration_folds: int = 3
    seed: int = 0

    def __post_init__(self) -> None:
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
    """Calibrated gradient-boosted trees, one per label in `LABELS`.

    Args:
        options: The settings; `BoostingOptions()` when None.

    Raises:
        InputError: For options that are not `BoostingOptions`.
    """

    def __init__(self, options: BoostingOptions | None = None) -> None:
        opt = BoostingOptions() if options is None else options
        if not isinstance(opt, BoostingOptions):
            raise InputError(f"options must be a BoostingOptions, got {type(opt).__name__}.")
        self.options = opt
        self._models: list[Any] | None = None
        self._width: int | None = None

    @property
    def is_fitted(self) -> bool:
        """Whether `fit` has run."""
        return self._models is not None

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

    def fit(self, X: np.ndarray, Y: np.ndarray) -> BoostedLabelClassifier:
        """Train one calibrated tree ensemble per label.

        Args:
            X: (S, D) segment features, finite.
            Y: (S, 6) bool (or 0/1) labels, columns in `LABELS` order.

        Returns:
            ``self``.

        Raises:
            InputError: For no segments, non-finite features, or labels of the wrong shape or
                values.
        """
        x = check_segment_features("X", X)
        y = check_segment_labels("Y", Y, x.shape[0])
        folds = self.options.calibration_folds
        models: list[Any] = []
        with threadpool_limits(limits=1):
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
        self._models = models
        self._width = x.shape[1]
        return self

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
        if self._models is None:
            raise NotFittedError("the classifier is not trained; call fit(X, Y) first.")
        x = check_segment_features("X", X, self._width)
        out = np.empty((x.shape[0], len(self._models)))
        with threadpool_limits(limits=1):
            for k, model in enumerate(self._models):
                out[:, k] = model if isinstance(model, float) else model.predict_proba(x)[:, 1]
        return out
