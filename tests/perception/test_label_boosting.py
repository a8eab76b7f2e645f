"""Calibrated boosted label classifiers: they learn a threshold rule a logistic regression
cannot, plug into the CV by scene, and refuse bad input.

Covers probaff.perception.label_boosting and the ``classifier`` of
probaff.perception.labels.cross_validate_labels.
"""

import numpy as np
import pytest

from probaff.errors import InputError, NotFittedError
from probaff.perception.label_boosting import BoostedLabelClassifier, BoostingOptions
from probaff.perception.labels import cross_validate_labels

_FAST = BoostingOptions(max_iter=20)


def _data(n=300, seed=0):
    """A band rule (0.3 < x0 < 0.7) no hyperplane separates; other labels simpler."""
    rng = np.random.default_rng(seed)
    x = rng.uniform(0.0, 1.0, size=(n, 4))
    band = (x[:, 0] > 0.3) & (x[:, 0] < 0.7)
    y = np.column_stack([band, x[:, 1] > 0.5, ~band, x[:, 2] > 0.2, band & (x[:, 3] > 0.5)])
    y = np.column_stack([y, np.zeros(n, dtype=bool)])  # a constant label
    return x, y, np.arange(n) % 8


def test_trees_beat_the_logistic_regression_on_a_band_rule():
    x, y, groups = _data()
    trees = cross_validate_labels(
        x, y, groups, n_splits=2, classifier=lambda: BoostedLabelClassifier(_FAST)
    )
    logistic = cross_validate_labels(x, y, groups, n_splits=2)
    assert trees.precision[0] > 0.9 and trees.recall[0] > 0.9
    assert logistic.recall[0] < 0.7 or logistic.precision[0] < 0.7
    assert np.all(trees.probabilities[:, 5] == 0.0)  # constant in training: predicted constant
    assert np.all((trees.probabilities >= 0.0) & (trees.probabilities <= 1.0))


def test_rare_labels_fit_without_calibration():
    x, y, _ = _data(n=60)
    y[:, 1] = False
    y[:2, 1] = True  # 2 positives < 3 calibration folds
    model = BoostedLabelClassifier(_FAST).fit(x, y)
    assert model.is_fitted and model.predict_proba(x).shape == (60, 6)


def test_bad_input_is_named():
    x, y, groups = _data(n=40)
    model = BoostedLabelClassifier(_FAST)
    with pytest.raises(NotFittedError, match="call fit"):
        model.predict_proba(x)
    model.fit(x, y)
    with pytest.raises(InputError, match="X"):
        model.predict_proba(x[:, :3])  # another feature width
    with pytest.raises(InputError, match="X"):
        model.fit(np.where(x > 0.5, np.nan, x), y)
    with pytest.raises(InputError, match="Y"):
        model.fit(x, y[:, :5])
    with pytest.raises(InputError, match="calibration must be one of"):
        BoostingOptions(calibration="platt")
    with pytest.raises(InputError, match="learning_rate"):
        BoostingOptions(learning_rate=0.0)
    with pytest.raises(InputError, match="options must be a BoostingOptions"):
        BoostedLabelClassifier({"max_iter": 3})  # type: ignore[arg-type]
    with pytest.raises(InputError, match="classifier must build"):
        cross_validate_labels(x, y, groups, n_splits=2, classifier=model)  # type: ignore[arg-type]
