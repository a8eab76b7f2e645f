import math
import warnings

import numpy as np
import pytest

from probaff.errors import InputError, NotFittedError, ProbaffError
from probaff.perception.labels import (
    LABELS,
    THESIS_PR,
    LabelClassifier,
    PerColumnLogistic,
    cross_validate_labels,
    label_index,
    reliability,
)
from probaff.perception.merge import MergeView, merge_views
from probaff.perception.refinement import label_entropy, purity_completeness, refine_segments

# ---------------------------------------------------------------- labels


def _segments(rng, n_scenes=10, per_scene=12, d=25):
    """Synthetic segments: label 0 separable with a margin, the others noisy linear rules."""
    x = rng.normal(size=(n_scenes * per_scene, d))
    x[:, 0] += np.where(x[:, 0] >= 0, 0.5, -0.5)  # margin of 1 around the boundary
    y = np.zeros((len(x), len(LABELS)), dtype=bool)
    y[:, 0] = x[:, 0] > 0
    for k in range(1, len(LABELS)):
        y[:, k] = x[:, k] + 0.5 * x[:, 7] + rng.normal(scale=0.5, size=len(x)) > 0
    groups = np.repeat(np.arange(n_scenes) * 7 + 3, per_scene)  # non-contiguous scene ids
    return x, y, groups


def test_label_index_and_unknown_name():
    assert [label_index(name) for name in LABELS] == list(range(6))
    assert label_index("graspable") == 5
    with pytest.raises(InputError, match="push_forward, push_backward"):
        label_index("pushable_up")


def test_thesis_average_is_mean_of_labels():
    rows = np.array([THESIS_PR[name] for name in LABELS])
    assert THESIS_PR["average"] == (81.8, 81.7)
    np.testing.assert_allclose(rows.mean(axis=0), THESIS_PR["average"], atol=0.05)


def test_cv_recovers_separable_label_and_never_shares_a_scene(rng):
    x, y, groups = _segments(rng)
    cv = cross_validate_labels(x, y, groups, n_splits=4, seed=0)
    assert cv.probabilities.shape == (len(x), 6)
    assert cv.precision[0] > 0.95 and cv.recall[0] > 0.95
    assert cv.average_precision[0] > 0.95 and cv.roc_auc[0] > 0.95
    # Noisy labels are learned but imperfectly.
    assert np.all(cv.roc_auc[1:] > 0.7) and np.all(cv.roc_auc[1:] < 0.99)
    assert 0.0 < cv.mean_precision <= 1.0 and 0.0 < cv.mean_recall <= 1.0
    # Each scene lies in exactly one test fold, so it is never in both train and test.
    for scene in np.unique(groups):
        assert len(np.unique(cv.folds[groups == scene])) == 1
    assert sorted(np.unique(cv.folds)) == [0, 1, 2, 3]
    assert cv.fold_roc_auc.shape == (4, 6)
    # Same seed, same result; another seed deals scenes differently.
    again = cross_validate_labels(x, y, groups, n_splits=4, seed=0)
    np.testing.assert_array_equal(again.probabilities, cv.probabilities)
    other = cross_validate_labels(x, y, groups, n_splits=4, seed=1)
    assert not np.array_equal(other.folds, cv.folds)


def test_out_of_fold_probabilities_come_from_models_without_that_scene(rng):
    x, y, groups = _segments(rng, n_scenes=4)
    cv = cross_validate_labels(x, y, groups, n_splits=4, seed=3)
    test = cv.folds == 0
    model = LabelClassifier().fit(x[~test], y[~test])
    np.testing.assert_allclose(cv.probabilities[test], model.predict_proba(x[test]))


def test_constant_label_is_handled_without_warnings(rng):
    x, y, groups = _segments(rng)
    y[:, 5] = False
    y[:, 4] = True
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        model = LabelClassifier().fit(x, y)
        p = model.predict_proba(x[:7])
        cv = cross_validate_labels(x, y, groups, seed=0)
    np.testing.assert_array_equal(p[:, 5], 0.0)
    np.testing.assert_array_equal(p[:, 4], 1.0)
    assert np.all((p[:, :4] > 0) & (p[:, :4] < 1))
    assert math.isnan(cv.precision[5]) and math.isnan(cv.recall[5])
    assert math.isnan(cv.average_precision[5]) and math.isnan(cv.roc_auc[5])
    assert cv.precision[4] == 1.0 and cv.recall[4] == 1.0
    assert np.all(np.isnan(cv.fold_roc_auc[:, 4:]))


def test_label_constant_in_a_training_fold(rng):
    x, y, groups = _segments(rng, n_scenes=4)
    only = groups == groups[0]
    y[:, 3] = only  # positive in one scene only: constant in that scene's training folds
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        cv = cross_validate_labels(x, y, groups, n_splits=4, seed=0)
    np.testing.assert_array_equal(cv.probabilities[only, 3], 0.0)
    assert cv.recall[3] == 0.0 and not cv.precision[3] > 0  # no true positive is ever found
    assert np.isnan(cv.fold_roc_auc[:, 3]).all()  # every test fold holds one scene


def test_reliability_of_calibrated_probabilities_is_diagonal(rng):
    p = rng.uniform(size=20000)
    y = rng.uniform(size=p.size) < p
    centres, frequency, counts = reliability(p, y, n_bins=10)
    np.testing.assert_allclose(centres, np.arange(0.05, 1.0, 0.1))
    assert counts.sum() == p.size
    se = np.sqrt(centres * (1 - centres) / counts)
    assert np.all(np.abs(frequency - centres) < 4 * se)
    # An overconfident predictor lies off the diagonal.
    _, skewed, _ = reliability(p, rng.uniform(size=p.size) < p**2, n_bins=10)
    assert np.max(np.abs(skewed - centres)) > 0.15


def test_reliability_edges_and_empty_bins():
    diagram = reliability(np.array([0.0, 1.0, 1.0, 0.55]), np.array([0, 1, 0, 1]), n_bins=4)
    np.testing.assert_array_equal(diagram.counts, [1, 0, 1, 2])
    np.testing.assert_array_equal(diagram.frequency[[0, 2, 3]], [0.0, 1.0, 0.5])
    assert math.isnan(diagram.frequency[1])


class _Columns(PerColumnLogistic):
    """The bare per-column regressions, as a subclass sees them."""

    C_NAME = "C of the columns"

    def fit(self, x, y):
        self._fit_columns(x, y)
        return self

    def predict_proba(self, x):
        return self._predict_columns(x)


def test_per_column_logistic_fits_each_column_and_keeps_constant_ones(rng):
    x = rng.normal(size=(40, 3))
    y = np.column_stack([x[:, 0] > 0, np.ones(40, bool), np.zeros(40, bool)])
    model = _Columns(C=2.0)
    assert not model.is_fitted
    with pytest.raises(NotFittedError, match="fit"):
        model.predict_proba(x)
    p = model.fit(x, y).predict_proba(x)
    assert model.is_fitted and p.shape == (40, 3)
    np.testing.assert_array_equal(p[:, 1:], np.tile([1.0, 0.0], (40, 1)))
    assert ((p[:, 0] >= 0.5) == y[:, 0]).mean() > 0.9
    with pytest.raises(InputError, match="C of the columns"):
        _Columns(C=0.0)
    with pytest.raises(InputError, match="max_iter"):
        _Columns(max_iter=0)


def test_label_errors(rng):
    x, y, groups = _segments(rng, n_scenes=3, per_scene=5)
    with pytest.raises(NotFittedError, match="fit"):
        LabelClassifier().predict_proba(x)
    bad = x.copy()
    bad[2, 4] = np.nan
    with pytest.raises(InputError, match="X contains 1 NaN"):
        LabelClassifier().fit(bad, y)
    with pytest.raises(InputError, match="Y has shape"):
        LabelClassifier().fit(x, y[:, :5])
    with pytest.raises(InputError, match="0/1"):
        LabelClassifier().fit(x, y * 2.0)
    with pytest.raises(InputError, match="empty"):
        LabelClassifier().fit(x[:0], y[:0])
    with pytest.raises(InputError, match="X must be a numeric array"):
        LabelClassifier().fit(np.full(x.shape, "a"), y)
    with pytest.raises(InputError, match="X has shape"):
        LabelClassifier().fit(x, y).predict_proba(x[:, :24])
    with pytest.raises(InputError, match="max_iter"):
        LabelClassifier(max_iter=0.5)
    with pytest.raises(InputError, match="n_splits=4 exceeds the 3 scene"):
        cross_validate_labels(x, y, groups, n_splits=4)
    with pytest.raises(InputError, match="n_splits"):
        cross_validate_labels(x, y, groups, n_splits=1)
    with pytest.raises(InputError, match="n_splits"):
        cross_validate_labels(x, y, groups, n_splits=2.5)
    with pytest.raises(InputError, match="groups has shape"):
        cross_validate_labels(x, y, groups[:-1], n_splits=2)
    with pytest.raises(InputError, match=r"p must lie in \[0, 1\]"):
        reliability(np.array([0.2, 1.2]), np.array([0, 1]))
    with pytest.raises(InputError, match="p is empty"):
        reliability(np.zeros(0), np.zeros(0))
    with pytest.raises(InputError, match="n_bins"):
        reliability(np.array([0.2]), np.array([1]), n_bins=0)


# ---------------------------------------------------------------- refinement

_CENTRES = np.array(
    [
        [0.95, 0.95, 0.05, 0.05, 0.95, 0.05],
        [0.05, 0.05, 0.95, 0.95, 0.05, 0.95],
        [0.95, 0.05, 0.95, 0.05, 0.05, 0.05],
    ]
)


def _check_tree(tree, n):
    root = tree.nodes[0]
    assert root.parent is None and root.depth == 0
    np.testing.assert_array_equal(root.members, np.arange(n))
    for node in tree.nodes:
        assert tree.nodes[node.index] is node
        assert node.entropy == pytest.approx(float(label_entropy(node.centroid)))
        if node.children:
            a, b = (tree.nodes[c] for c in node.children)
            assert a.parent == b.parent == node.index and a.depth == b.depth == node.depth + 1
            merged = np.sort(np.concatenate([a.members, b.members]))
            np.testing.assert_array_equal(merged, node.members)
            assert min(a.entropy, b.entropy) < node.entropy  # the thesis's rule
            assert a.entropy <= b.entropy


def test_label_entropy_values():
    assert float(label_entropy(np.full(6, 0.5))) == pytest.approx(3 * math.log(2))
    assert float(label_entropy(np.array([0, 1, 0, 1, 1, 0.0]))) == 0.0
    assert label_entropy(np.full((4, 2, 6), 0.3)).shape == (4, 2)
    with pytest.raises(InputError, match="last axis"):
        label_entropy(np.full(5, 0.5))


def test_three_clusters_become_three_objects(rng):
    true = np.repeat(np.arange(3), 10)
    order = rng.permutation(len(true))
    true = true[order]
    tree = refine_segments(_CENTRES[true], seed=0)
    _check_tree(tree, len(true))
    assert len(tree.leaves) == 3 and tree.depth == 2
    assert purity_completeness(tree.groups(), true) == (1.0, 1.0)
    # The first split separates one object from the other two.
    assert len(np.unique(tree.groups_at_depth(1))) == 2
    np.testing.assert_array_equal(tree.groups_at_depth(0), 0)
    # Lower entropy at every kept split down to the leaves (Fig. 2.8b).
    assert max(leaf.entropy for leaf in tree.leaves) < tree.nodes[0].entropy


def test_noisy_clusters_keep_splitting_under_the_thesis_rule(rng):
    true = np.repeat(np.arange(3), 4)
    P = np.clip(_CENTRES[true] + rng.normal(scale=0.01, size=(12, 6)), 0, 1)
    tree = refine_segments(P, seed=0)
    _check_tree(tree, 12)
    # H is strictly concave, so any two distinct vectors split: every leaf is one segment.
    assert len(tree.leaves) == 12
    purity, completeness = purity_completeness(tree.groups(), true)
    assert purity == 1.0 and completeness == pytest.approx(0.25)
    # A minimum gain stops the splits within an object.
    gated = refine_segments(P, seed=0, min_gain=0.1)
    assert purity_completeness(gated.groups(), true) == (1.0, 1.0)
    assert len(gated.leaves) == 3


def test_no_split_when_entropy_would_not_fall():
    same = np.tile(_CENTRES[0], (6, 1))
    tree = refine_segments(same)
    assert len(tree.nodes) == 1 and tree.nodes[0].is_leaf
    np.testing.assert_array_equal(tree.groups(), 0)
    # Two vectors whose split lowers the entropy by less than min_gain stay together.
    close = np.stack([_CENTRES[0], np.clip(_CENTRES[0] + 0.01, 0, 1)])
    gain = float(label_entropy(close.mean(axis=0)) - label_entropy(close).min())
    assert 0 < gain < 0.05
    assert len(refine_segments(close, min_gain=0.05).nodes) == 1
    assert len(refine_segments(close, min_gain=0.0).leaves) == 2


def test_split_limits_and_determinism(rng):
    true = np.repeat(np.arange(3), 4)
    P = np.clip(_CENTRES[true] + rng.normal(scale=0.05, size=(12, 6)), 0, 1)
    shallow = refine_segments(P, max_depth=1)
    assert shallow.depth == 1 and len(shallow.leaves) == 2
    big = refine_segments(P, min_size=3)
    assert min(len(leaf.members) for leaf in big.leaves) >= 3
    _check_tree(big, 12)
    a, b = refine_segments(P, seed=5, min_size=2), refine_segments(P, seed=5, min_size=2)
    assert [n.members.tolist() for n in a.nodes] == [n.members.tolist() for n in b.nodes]


def test_purity_completeness_known_values():
    pred = np.array([0, 0, 1, 1])
    true = np.array([0, 0, 0, 1])
    purity, completeness = purity_completeness(pred, true)
    assert purity == pytest.approx((1 + 0.5) / 2)
    assert completeness == pytest.approx((2 / 3 + 1) / 2)
    purity, completeness = purity_completeness(pred, true, weights=np.array([1, 1, 10, 1]))
    assert purity == pytest.approx((1 + 10 / 11) / 2)
    assert completeness == pytest.approx((10 / 12 + 1) / 2)
    assert purity_completeness(np.array(["a", "b"]), np.array([7, 9])) == (1.0, 1.0)


def test_refinement_errors():
    good = np.tile(_CENTRES[0], (3, 1))
    bad = good.copy()
    bad[0, 0] = np.nan
    with pytest.raises(InputError, match="P contains 1 NaN"):
        refine_segments(bad)
    with pytest.raises(InputError, match=r"P must lie in \[0, 1\]"):
        refine_segments(good * 1.5)
    with pytest.raises(InputError, match="P has shape"):
        refine_segments(good[:, :5])
    with pytest.raises(InputError, match="P is empty"):
        refine_segments(good[:0])
    with pytest.raises(InputError, match="min_size"):
        refine_segments(good, min_size=0)
    with pytest.raises(InputError, match="max_depth"):
        refine_segments(good, max_depth=-1)
    with pytest.raises(InputError, match="min_gain"):
        refine_segments(good, min_gain=-0.1)
    with pytest.raises(InputError, match="weights must be > 0"):
        purity_completeness(np.array([0, 1]), np.array([0, 1]), weights=np.array([1.0, 0.0]))
    with pytest.raises(InputError, match="true_ids has shape"):
        purity_completeness(np.array([0, 1]), np.array([0, 1, 2]))
    with pytest.raises(InputError, match="pred_groups is empty"):
        purity_completeness(np.zeros(0), np.zeros(0))


# ---------------------------------------------------------------- merge


def _view(rng, n=5):
    centroids = np.stack([np.arange(n) * 0.4, rng.uniform(-1, 1, n), rng.uniform(0, 1, n)], 1)
    labels = (rng.uniform(size=(n, 6)) > 0.5).astype(float) * 0.8 + 0.1
    counts = rng.integers(50, 500, size=n)
    return centroids, labels, counts


def test_merge_links_two_views_shifted_by_a_centimetre(rng):
    c, lab, n = _view(rng)
    c2 = c + np.array([0.01, 0.0, 0.0])
    lab2 = np.clip(lab + rng.normal(scale=0.05, size=lab.shape), 0, 1)
    n2 = rng.integers(50, 500, size=len(n))
    merged = merge_views([(c, lab, n), (c2, lab2, n2)], proximity="centroid")
    assert len(merged.point_counts) == 5
    np.testing.assert_array_equal(merged.membership[0], np.arange(5))
    np.testing.assert_array_equal(merged.membership[1], np.arange(5))
    np.testing.assert_array_equal(merged.point_counts, n + n2)
    w = (n / (n + n2))[:, None]
    np.testing.assert_allclose(merged.centroids, w * c + (1 - w) * c2)
    np.testing.assert_allclose(merged.label_vectors, w * lab + (1 - w) * lab2)
    np.testing.assert_array_equal(merged.n_views, 2)


def test_merge_keeps_distant_or_different_segments_apart():
    lab = np.array([[0.9, 0.9, 0.1, 0.1, 0.9, 0.1]])
    other = np.array([[0.1, 0.1, 0.9, 0.9, 0.9, 0.1]])
    here = np.zeros((1, 3))
    far = np.array([[0.10, 0.0, 0.0]])
    one = np.array([100])

    def count(a, b, **kw):
        return len(merge_views([a, b], proximity="centroid", **kw).point_counts)

    assert count((here, lab, one), (far, lab, one)) == 2
    assert count((here, lab, one), (here, other, one)) == 2
    # The label threshold is strict at 0.7: 0.69 links, 0.71 does not.
    near = np.array([[0.0, 0.0, 0.04]])
    for step, expected in ((0.69, 1), (0.71, 2)):
        shifted = lab.copy()
        shifted[0, 0] -= step
        assert count((here, lab, one), (near, shifted, one)) == expected
    # A larger proximity threshold links the 10 cm pair.
    assert count((here, lab, one), (far, lab, one), max_distance=0.2) == 1


def test_merge_never_links_within_a_view_but_joins_through_another():
    lab = np.full((2, 6), 0.5)
    pair = np.array([[0.0, 0.0, 0.0], [0.04, 0.0, 0.0]])
    counts = np.array([10, 30])
    alone = merge_views([(pair, lab, counts)], proximity="centroid")
    np.testing.assert_array_equal(alone.membership[0], [0, 1])
    bridge = merge_views(
        [(pair, lab, counts), (np.array([[0.02, 0.0, 0.0]]), lab[:1], [20])],
        proximity="centroid",
    )
    assert len(bridge.point_counts) == 1 and bridge.point_counts[0] == 60
    np.testing.assert_allclose(bridge.centroids[0], [(0.04 * 30 + 0.02 * 20) / 60, 0, 0])
    # An empty view is allowed and gets an empty membership.
    with_empty = merge_views(
        [(pair, lab, counts), (np.zeros((0, 3)), np.zeros((0, 6)), [])], proximity="centroid"
    )
    assert with_empty.membership[1].shape == (0,)


def _strip(x0, x1, y=0.0, z=0.0, step=0.01):
    """A row of points along x from x0 to x1 (m) at (y, z), `step` apart."""
    x = np.arange(x0, x1 + step / 2, step)
    return np.stack([x, np.full(len(x), y), np.full(len(x), z)], axis=1)


def _point_view(strips, labels, noise=None):
    """A `MergeView` of one segment per strip: its centroid, label vector and points."""
    pts = np.concatenate(strips)
    rows = np.repeat(np.arange(len(strips)), [len(s) for s in strips])
    if noise is not None:  # points of no segment, row -1
        pts, rows = np.concatenate([pts, noise]), np.concatenate([rows, np.full(len(noise), -1)])
    return MergeView(
        centroids=np.array([s.mean(axis=0) for s in strips]),
        label_vectors=np.asarray(labels, dtype=float),
        point_counts=np.array([len(s) for s in strips]),
        points=pts,
        point_segments=rows,
    )


def test_merge_points_links_overlapping_segments_whose_centroids_lie_far_apart():
    lab = np.array([[0.9, 0.9, 0.1, 0.1, 0.9, 0.1]])
    # One table edge seen by two views: x in [0, 1] m and [0.6, 1.6] m, overlapping by 0.4 m;
    # the centroids lie 0.6 m apart.
    a = _point_view([_strip(0.0, 1.0)], lab)
    b = _point_view([_strip(0.6, 1.6)], lab)
    assert np.linalg.norm(a.centroids[0] - b.centroids[0]) == pytest.approx(0.6)
    merged = merge_views([a, b], proximity="points")
    assert len(merged.point_counts) == 1 and merged.point_counts[0] == 101 + 101
    np.testing.assert_array_equal(merged.n_views, [2])
    np.testing.assert_allclose(merged.centroids[0], [0.8, 0.0, 0.0])
    assert len(merge_views([a, b], proximity="centroid").point_counts) == 2
    assert len(merge_views([a, b]).point_counts) == 1  # the points proximity is the default


def test_merge_points_threshold_is_the_gap_between_the_nearest_points():
    lab = np.array([[0.9, 0.9, 0.1, 0.1, 0.9, 0.1]])
    a = _point_view([_strip(0.0, 1.0)], lab)
    # Abutting strips: 4 cm and 6 cm past the first strip's end (x = 1 m), and beside it.
    for gap, expected in ((0.04, 1), (0.06, 2)):
        b = _point_view([_strip(1.0 + gap, 2.0 + gap)], lab)
        assert len(merge_views([a, b]).point_counts) == expected, gap
        side = _point_view([_strip(0.0, 1.0, y=gap)], lab)
        assert len(merge_views([a, side]).point_counts) == expected, gap
    # A larger threshold links the 6 cm pair; points of no segment (row -1) play no part.
    b = _point_view([_strip(1.06, 2.06)], lab, noise=_strip(1.01, 1.05))
    assert len(merge_views([a, b]).point_counts) == 2
    assert len(merge_views([a, b], max_distance=0.07).point_counts) == 1


def test_merge_points_label_distance_still_gates_and_views_do_not_self_link():
    lab = np.array([[0.9, 0.9, 0.1, 0.1, 0.9, 0.1]])
    other = np.array([[0.1, 0.1, 0.9, 0.9, 0.9, 0.1]])  # 1.6 from lab
    a = _point_view([_strip(0.0, 1.0)], lab)
    b = _point_view([_strip(0.5, 1.5)], other)
    assert len(merge_views([a, b]).point_counts) == 2
    for step, expected in ((0.69, 1), (0.71, 2)):
        shifted = lab.copy()
        shifted[0, 0] -= step
        c = _point_view([_strip(0.5, 1.5)], shifted)
        assert len(merge_views([a, c]).point_counts) == expected
    # Two touching segments of one view stay apart, and join through a third of another view:
    # a small segment next to the big one (8 cm to its right), bridged by one in between.
    pair = _point_view([_strip(0.0, 1.0), _strip(1.08, 1.3)], np.repeat(lab, 2, axis=0))
    np.testing.assert_array_equal(merge_views([pair]).membership[0], [0, 1])
    bridge = _point_view([_strip(1.0, 1.1)], lab)
    merged = merge_views([pair, bridge])
    assert len(merged.point_counts) == 1 and merged.point_counts[0] == 101 + 23 + 11
    # A view without segments (its points, if any, in none) takes no part.
    empty = MergeView(np.zeros((0, 3)), np.zeros((0, 6)), np.zeros(0), _strip(1, 2), [-1] * 101)
    merged = merge_views([pair, empty, bridge])
    assert len(merged.point_counts) == 1 and merged.membership[1].shape == (0,)


def test_merge_points_nearest_pair_not_hidden_by_a_closer_segment():
    # Each point of `a` is nearer to b's segment 0 than to its segment 1, yet a lies within
    # 4 cm of segment 1; segment 0's labels differ from a's.
    lab = np.array([[0.9, 0.9, 0.1, 0.1, 0.9, 0.1]])
    other = np.array([[0.1, 0.1, 0.9, 0.9, 0.9, 0.1]])
    a = _point_view([_strip(0.0, 0.2)], lab)
    b = _point_view([_strip(0.0, 0.2, z=0.01), _strip(0.0, 0.2, z=0.04)], np.vstack([other, lab]))
    merged = merge_views([a, b])
    np.testing.assert_array_equal(merged.membership[0], [0])
    np.testing.assert_array_equal(merged.membership[1], [1, 0])


def test_merge_points_matches_brute_force(rng):
    # Random blobs in three views: the merged segments are the connected components of the
    # links found from all pairwise point distances.
    from scipy.sparse.csgraph import connected_components
    from scipy.spatial.distance import cdist

    views, sets = [], []
    for v in range(3):
        centres = rng.uniform(0, 0.6, size=(6, 3))
        blobs = [c + rng.normal(scale=0.03, size=(int(rng.integers(5, 40)), 3)) for c in centres]
        lab = np.clip(0.5 + rng.normal(scale=0.3, size=(6, 6)), 0, 1)
        views.append(_point_view(blobs, lab))
        sets += [(v, b, lab[k]) for k, b in enumerate(blobs)]
    links = np.array(
        [
            [
                vi != vj and cdist(bi, bj).min() < 0.05 and np.linalg.norm(li - lj) < 0.7
                for vj, bj, lj in sets
            ]
            for vi, bi, li in sets
        ]
    )
    assert 0 < links.sum() < links.size / 4  # some links, not all
    _, component = connected_components(links, directed=False)
    group = np.concatenate(merge_views(views).membership)
    # The same partition: equal groups exactly where the components are equal.
    np.testing.assert_array_equal(group[:, None] == group, component[:, None] == component)


def test_merge_errors(rng):
    c, lab, n = _view(rng, 3)
    with pytest.raises(InputError, match="views is empty"):
        merge_views([])
    with pytest.raises(InputError, match="triple"):
        merge_views([(c, lab)])
    bad = c.copy()
    bad[1, 2] = np.inf
    with pytest.raises(InputError, match=r"views\[0\] centroids contains 1 NaN or infinite"):
        merge_views([(bad, lab, n)], proximity="centroid")
    with pytest.raises(InputError, match=r"views\[1\] label_vectors must lie in \[0, 1\]"):
        merge_views([(c, lab, n), (c, lab + 1, n)], proximity="centroid")
    with pytest.raises(InputError, match="label_vectors has shape"):
        merge_views([(c, lab[:, :5], n)], proximity="centroid")
    with pytest.raises(InputError, match="point_counts has shape"):
        merge_views([(c, lab, n[:2])], proximity="centroid")
    with pytest.raises(InputError, match="positive integers"):
        merge_views([(c, lab, n * 0)], proximity="centroid")
    with pytest.raises(InputError, match="positive integers"):
        merge_views([(c, lab, n + 0.5)], proximity="centroid")
    with pytest.raises(InputError, match="no segments"):
        merge_views([(np.zeros((0, 3)), np.zeros((0, 6)), np.zeros(0))], proximity="centroid")
    with pytest.raises(InputError, match="max_distance"):
        merge_views([(c, lab, n)], proximity="centroid", max_distance=0.0)
    with pytest.raises(InputError, match="numeric"):
        merge_views([(c, lab, ["a", "b", "c"])], proximity="centroid")
    assert issubclass(InputError, ProbaffError)


def test_merge_proximity_and_point_errors():
    lab = np.full((2, 6), 0.5)
    view = _point_view([_strip(0.0, 0.1), _strip(0.5, 0.6)], lab)
    c, n = view.centroids, view.point_counts
    pts, rows = view.points, view.point_segments

    def with_points(points, point_segments):
        return MergeView(c, lab, n, points, point_segments)

    with pytest.raises(InputError, match="proximity must be one of 'points', 'centroid'"):
        merge_views([view], proximity="centroids")
    with pytest.raises(InputError, match=r"views \[0\] give no points.*proximity='centroid'"):
        merge_views([(c, lab, n)])
    with pytest.raises(InputError, match=r"views\[0\] points has shape"):
        merge_views([with_points(pts[:, :2], rows)])
    with pytest.raises(InputError, match=r"views\[0\] point_segments has shape"):
        merge_views([with_points(pts, rows[:-1])])
    nan = pts.copy()
    nan[3, 1] = np.nan
    with pytest.raises(InputError, match=r"views\[0\] points contains 1 NaN"):
        merge_views([with_points(nan, rows)])
    # Point rows must name the view's segments: a row past them, or a segment without points.
    with pytest.raises(InputError, match=r"row in \[0, 2\)"):
        merge_views([with_points(pts, np.where(rows == 1, 2, rows))])
    with pytest.raises(InputError, match=r"row in \[0, 2\)"):
        merge_views([with_points(pts, rows - 0.5)])
    with pytest.raises(InputError, match=r"no point to segment\(s\) \[1\] of its 2"):
        merge_views([with_points(pts, np.where(rows == 1, -1, rows))])
    with pytest.raises(InputError, match="without point_segments"):
        merge_views([with_points(pts, None)])
    with pytest.raises(InputError, match="MergeView or a"):
        merge_views(["abc"])


# ------------------------------------------------------------------ non-numeric input

_WORDS = [["a"] * 6 for _ in range(3)]


@pytest.mark.parametrize(
    ("call", "name"),
    [
        (lambda: LabelClassifier().fit(_WORDS, np.zeros((3, 6), bool)), "X"),
        (lambda: reliability(["p", "q"], [0, 1]), "p"),
        (lambda: refine_segments(_WORDS), "P"),
        (lambda: label_entropy(_WORDS), "P"),
        (lambda: purity_completeness([0, 1], [0, 1], weights=["w", "v"]), "weights"),
        (
            lambda: merge_views([(_WORDS[:1], np.zeros((1, 6)), np.ones(1))], proximity="centroid"),
            r"views\[0\] centroids",
        ),
    ],
    ids=["classifier", "reliability", "refine", "entropy", "purity", "merge"],
)
def test_strings_are_a_clear_error(call, name):
    with pytest.raises(InputError, match=rf"{name} must be a numeric array"):
        call()
