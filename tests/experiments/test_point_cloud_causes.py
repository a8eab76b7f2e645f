"""The chapter 2 error breakdown, the scene-bootstrap intervals and the truth figure.

Covers probaff.experiments.point_cloud_labels.causes,
probaff.experiments.point_cloud_labels.intervals,
probaff.experiments.point_cloud_labels.truth_figure.
"""

import math

import numpy as np
import pytest

from probaff.errors import InputError
from probaff.experiments.point_cloud_labels.causes import CAUSES, attribute_errors, cause_table
from probaff.experiments.point_cloud_labels.intervals import interval_text, scene_intervals
from probaff.experiments.point_cloud_labels.truth_figure import plot_labels_against_truth
from probaff.perception.labels import LABELS

_F = np.zeros((6, 6), dtype=bool)


def _case():
    """Six segments, label 0 only: each wrong in a way that one cause explains."""
    truth = _F.copy()
    truth[:, 0] = [1, 1, 1, 1, 1, 0]
    baseline = _F.copy()  # every positive missed, the negative right
    mixed, whole, capacity, features = _F.copy(), _F.copy(), _F.copy(), _F.copy()
    fragment = np.array([0, 1, 0, 0, 0, 0], dtype=bool)
    mixed[0, 0] = True  # 0: under-segmented
    whole[1, 0] = True  # 1: a fragment whose whole object is right
    whole[2, 0] = True  # 2: whole object right but not a fragment: not over-segmentation
    capacity[2, 0] = True  # ... the trees on the same features fix it
    features[3, 0] = True  # 3: only the richer features fix it
    return (
        truth,
        baseline,
        dict(
            mixed=mixed, fragment=fragment, whole_object=whole, capacity=capacity, features=features
        ),
    )


def test_each_error_gets_the_first_cause_that_explains_it():
    truth, baseline, masks = _case()
    causes = attribute_errors(truth, baseline, **masks)
    assert causes[:, 0].tolist() == [0, 1, 2, 3, 4, -1]  # 4: the residual, label rules
    assert np.all(causes[:, 1:] == -1)
    rows = cause_table(truth, baseline, causes)
    assert [r["label"] for r in rows] == [*LABELS, "all"]
    first, total = rows[0], rows[-1]
    assert (first["tp"], first["fp"], first["fn"], first["tn"]) == (0, 0, 5, 1)
    assert first["errors"] == total["errors"] == 5
    assert [first[f"{c}_pct"] for c in CAUSES] == [20.0] * 5
    assert math.isnan(rows[1]["features_pct"])  # no error on label 1
    assert total["tn"] == 1 + 5 * 6


def test_breakdown_rejects_bad_input():
    truth, baseline, masks = _case()
    with pytest.raises(InputError, match="fragment"):
        attribute_errors(truth, baseline, **{**masks, "fragment": masks["fragment"][:3]})
    with pytest.raises(InputError, match="mixed must be bool or 0/1"):
        attribute_errors(truth, baseline, **{**masks, "mixed": masks["mixed"] * 2.0})
    causes = attribute_errors(truth, baseline, **masks)
    with pytest.raises(InputError, match="causes must be -1 exactly where"):
        cause_table(truth, ~baseline, causes)
    with pytest.raises(InputError, match="causes must be integers"):
        cause_table(truth, baseline, causes + 3)


def test_scene_intervals_pool_and_bracket():
    rng = np.random.default_rng(0)
    groups = np.repeat(np.arange(10), 20)
    truth = rng.random((200, 6)) < 0.5
    flip = rng.random((200, 6)) < 0.2  # about 80 % of the decisions right
    prob = np.where(truth ^ flip, 0.9, 0.1)
    rows = scene_intervals(truth, prob, groups, n_boot=300)
    assert [r["label"] for r in rows] == [*LABELS, "average"]
    decided = prob >= 0.5
    tp = (truth & decided).sum(axis=0)
    np.testing.assert_allclose(
        [r["precision_pct"] for r in rows[:6]], 100 * tp / decided.sum(axis=0)
    )
    np.testing.assert_allclose([r["recall_pct"] for r in rows[:6]], 100 * tp / truth.sum(axis=0))
    assert rows[6]["precision_pct"] == pytest.approx(
        np.mean([r["precision_pct"] for r in rows[:6]])
    )
    for r in rows:
        assert r["precision_lo"] < r["precision_pct"] < r["precision_hi"]
        assert r["recall_lo"] < r["recall_pct"] < r["recall_hi"]
        assert r["recall_hi"] - r["recall_lo"] < 25.0
    perfect = scene_intervals(truth, truth.astype(float), groups, n_boot=50)
    assert all(r["precision_lo"] == r["precision_hi"] == 100.0 for r in perfect)
    none = scene_intervals(truth, np.zeros((200, 6)), groups, n_boot=50)
    assert math.isnan(none[0]["precision_pct"]) and none[0]["recall_pct"] == 0.0
    with pytest.raises(InputError, match="probabilities"):
        scene_intervals(truth, prob[:, :5], groups)
    with pytest.raises(InputError, match="n_boot"):
        scene_intervals(truth, prob, groups, n_boot=0)


def test_truth_figure_is_written_and_rejects_bad_input(tmp_path):
    rng = np.random.default_rng(0)
    points = rng.uniform(0.0, 2.0, size=(300, 3))
    rows = rng.integers(-1, 4, size=300)
    truth = rng.random((4, 6)) < 0.5
    models = {"thesis": rng.random((4, 6)), "new": truth.astype(float)}
    path = plot_labels_against_truth(points, rows, truth, models, tmp_path / "t.png")
    assert (tmp_path / "t.png").stat().st_size > 0 and path.endswith("t.png")
    with pytest.raises(InputError, match="models is empty"):
        plot_labels_against_truth(points, rows, truth, {}, tmp_path / "u.png")
    with pytest.raises(InputError, match=r"models\['new'\]"):
        plot_labels_against_truth(
            points, rows, truth, {"new": models["new"] * 2}, tmp_path / "u.png"
        )
    with pytest.raises(InputError, match="point_segments must hold rows"):
        plot_labels_against_truth(points, rows + 5, truth, models, tmp_path / "u.png")
    with pytest.raises(InputError, match="points"):
        plot_labels_against_truth(points * np.nan, rows, truth, models, tmp_path / "u.png")


def test_scene_intervals_take_per_segment_thresholds():
    rng = np.random.default_rng(1)
    groups = np.repeat(np.arange(5), 20)
    truth = rng.random((100, 6)) < 0.5
    prob = rng.random((100, 6))
    cut = rng.uniform(0.2, 0.8, size=(100, 6))
    rows = scene_intervals(truth, prob, groups, n_boot=50, thresholds=cut)
    same = scene_intervals(truth, (prob >= cut).astype(float), groups, n_boot=50)
    assert rows == same  # p >= its own threshold, as the 0/1 decisions at 0.5
    high = scene_intervals(truth, prob, groups, n_boot=50, thresholds=0.9)
    decided = prob >= 0.9
    assert high[0]["recall_pct"] == pytest.approx(
        100 * (truth & decided)[:, 0].sum() / truth[:, 0].sum()
    )
    with pytest.raises(InputError, match="thresholds"):
        scene_intervals(truth, prob, groups, thresholds=cut[:, :5])
    with pytest.raises(InputError, match="thresholds must be finite"):
        scene_intervals(truth, prob, groups, thresholds=np.nan)


def test_a_label_without_positives_drops_out_of_the_mean_and_the_row_reads_as_text():
    truth = np.zeros((4, 6), dtype=bool)
    truth[:2, 0] = truth[1:3, 1] = True  # labels 2-5 have no positive: no recall
    decided = truth.copy()
    decided[3, 0] = True  # label 0: precision 2/3; nothing else predicted wrong
    (row,) = scene_intervals(truth, decided.astype(float), np.arange(4), n_boot=200)[-1:]
    assert row["precision_pct"] == pytest.approx((200 / 3 + 100) / 2)
    assert row["recall_pct"] == 100.0 == row["recall_lo"] == row["recall_hi"]
    assert row["precision_lo"] < row["precision_pct"] <= row["precision_hi"] == 100.0
    assert interval_text(row) == f"83.3 [{row['precision_lo']:.1f}, 100.0] / 100.0 [100.0, 100.0]"
    # nothing predicted and nothing true: both means are undefined and read n/a
    nothing = np.zeros((4, 6), dtype=bool)
    (empty,) = scene_intervals(nothing, nothing.astype(float), np.arange(4), n_boot=20)[-1:]
    assert math.isnan(empty["precision_pct"]) and math.isnan(empty["recall_pct"])
    assert interval_text(empty) == "n/a / n/a"
