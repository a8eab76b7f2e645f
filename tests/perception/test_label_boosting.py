"""Calibrated boosted label classifiers: they learn a threshold rule a logistic regression
cannot, plug into the CV by scene, and refuse bad input.

Covers probaff.perception.label_boosting (with its per-label decision thresholds, chosen on
the training scenes only), the ``classifier`` of
probaff.perception.labels.cross_validate_labels and the thresholds of
probaff.experiments.point_cloud_labels.comparison.compare_models.
"""

import numpy as np
import pytest

from probaff.errors import InputError, NotFittedError
from probaff.experiments.point_cloud_labels.comparison import compare_models
from probaff.perception.label_boosting import (
    BoostedLabelClassifier,
    BoostingOptions,
    best_threshold,
)
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


def _graded(n=4000, seed=1):
    """Six labels with P(label k | x) = x_k, x uniform on [0, 1]^6, and 10 scenes.

    The calibrated probability of label k is x_k itself, so the F1 score of ``p >= t`` is
    ``(1 - t^2) / (1.5 - t)``, largest at ``t = (3 - sqrt 5) / 2 = 0.382``; precision
    ``(1 + t) / 2`` and recall ``1 - t^2`` meet at ``t = 0.5``.
    """
    rng = np.random.default_rng(seed)
    x = rng.uniform(0.0, 1.0, size=(n, 6))
    return x, rng.uniform(size=(n, 6)) < x, np.arange(n) % 10


_F1_BEST = (3.0 - np.sqrt(5.0)) / 2.0


def test_best_threshold_finds_the_known_optimum():
    x, y, _ = _graded(n=20000)
    assert best_threshold(y[:, 0], x[:, 0], "f1") == pytest.approx(_F1_BEST, abs=0.03)
    assert best_threshold(y[:, 0], x[:, 0], "balanced") == pytest.approx(0.5, abs=0.03)
    assert best_threshold(y[:, 0], x[:, 0], "fixed") == 0.5
    # a perfect ranker: the threshold separates the classes, midway between them
    p = np.array([0.1, 0.2, 0.3, 0.8, 0.9])
    assert best_threshold(p > 0.5, p, "f1") == pytest.approx(0.55)
    # nothing to choose: one value, or a constant label
    assert best_threshold(np.array([True, False]), np.array([0.3, 0.3])) == 0.5
    assert best_threshold(np.zeros(3, bool), np.array([0.1, 0.2, 0.3])) == 0.5


def test_fit_chooses_each_labels_threshold_near_the_known_optimum():
    x, y, groups = _graded()
    f1 = BoostedLabelClassifier(BoostingOptions(max_iter=30, threshold="f1")).fit(x, y, groups)
    np.testing.assert_allclose(f1.thresholds, _F1_BEST, atol=0.08)
    assert np.array_equal(f1.predict(x), f1.predict_proba(x) >= f1.thresholds)
    balanced = BoostedLabelClassifier(BoostingOptions(max_iter=30, threshold="balanced"))
    np.testing.assert_allclose(balanced.fit(x, y, groups).thresholds, 0.5, atol=0.08)
    fixed = BoostedLabelClassifier(BoostingOptions(max_iter=30, threshold=0.7)).fit(x, y)
    np.testing.assert_array_equal(fixed.thresholds, 0.7)
    assert BoostedLabelClassifier(BoostingOptions(threshold="fixed")).options.threshold == "fixed"


def test_thresholds_come_from_the_training_scenes_only():
    """A fold's thresholds (and probabilities) do not move when its test scenes' labels do."""
    rng = np.random.default_rng(2)
    n, scenes = 240, 6
    groups = np.arange(n) % scenes
    features = rng.uniform(size=(n, 25))
    labels = rng.uniform(size=(n, 6)) < features[:, :6]
    data = {
        "features": features,
        "context": rng.uniform(size=(n, 23)),
        "labels": labels,
        "groups": groups,
        "point_counts": np.full(n, 100),
        "mixed": np.zeros((n, 6), bool),
        "fragment": np.zeros(n, bool),
        "oracle_rows": np.full(n, -1),
        "oracle_features": features[:40],
        "oracle_labels": labels[:40],
        "oracle_groups": groups[:40],
    }
    quick = BoostingOptions(max_iter=5, calibration_folds=2, threshold_folds=2)
    kwargs = {"n_splits": 2, "seed": 0, "n_boot": 20, "options": quick}
    before = compare_models(data, **kwargs)
    test_scenes = np.unique(
        groups[before.thresholds["new"][:, 0] == before.thresholds["new"][0, 0]]
    )
    in_test = np.isin(groups, test_scenes)
    flipped = {**data, "labels": np.where(in_test[:, None], ~labels, labels)}
    after = compare_models(flipped, **kwargs)
    for name in ("capacity", "new"):
        np.testing.assert_array_equal(
            after.thresholds[name][in_test], before.thresholds[name][in_test]
        )
        np.testing.assert_array_equal(
            after.probabilities[name][in_test], before.probabilities[name][in_test]
        )
    assert not np.array_equal(after.thresholds["new"][~in_test], before.thresholds["new"][~in_test])
    np.testing.assert_array_equal(before.thresholds["thesis"], 0.5)
    np.testing.assert_array_equal(
        before.decisions("new"), before.probabilities["new"] >= before.thresholds["new"]
    )


@pytest.mark.parametrize(
    ("options", "message"),
    [
        ({"threshold": "best"}, "threshold must be one of 'fixed', 'f1', 'balanced'"),
        ({"threshold": 1.0}, r"threshold must be .* a number in \(0, 1\)"),
        ({"threshold": 0}, "threshold must be"),
        ({"threshold": float("nan")}, "threshold must be"),
        ({"threshold": True}, "threshold must be"),
        ({"threshold": None}, "threshold must be"),
        ({"threshold_folds": 1}, "threshold_folds must be an integer >= 2"),
    ],
)
def test_bad_threshold_options_are_named(options, message):
    with pytest.raises(InputError, match=message):
        BoostingOptions(**options)


def test_bad_threshold_input_is_named():
    x, y, groups = _data(n=40)
    with pytest.raises(NotFittedError, match="call fit"):
        _ = BoostedLabelClassifier(_FAST).thresholds
    with pytest.raises(InputError, match="groups"):
        BoostedLabelClassifier(_FAST).fit(x, y, groups[:-1])
    with pytest.raises(InputError, match="rule must be one of"):
        best_threshold(y[:, 0], x[:, 0], "accuracy")
    with pytest.raises(InputError, match="truth"):
        best_threshold(y[:-1, 0], x[:, 0])
    with pytest.raises(InputError, match="probabilities"):
        best_threshold(y[:, 0], np.full(40, np.nan))
