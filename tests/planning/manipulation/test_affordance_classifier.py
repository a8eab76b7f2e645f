"""The per-direction affordance classifier: training, cell predictions, cross-validation."""

import dataclasses

import numpy as np
import pytest

from probaff.errors import InputError
from probaff.planning.manipulation.classifier import AffordanceClassifier, collect_voxels, evaluate
from probaff.sim.warehouse_config import load_warehouse


@pytest.fixture(scope="module")
def data():
    return collect_voxels(load_warehouse(), 3, np.random.default_rng(0))


def test_dataset(data):
    n = len(data.features)
    assert data.features.shape == (n, len(data.names)) and np.isfinite(data.features).all()
    assert data.labels.shape == (n, 4) and data.labels.dtype == bool
    assert data.cell_ids.shape == data.map_ids.shape == (n,)
    assert set(data.map_ids.tolist()) == {0, 1, 2}
    np.testing.assert_array_equal(data.cell_ids // 144, data.map_ids)
    assert (data.coverage > 0.95).all()  # the head camera: a few phantom hits by walls
    assert 0 <= data.unseen_boxes < data.n_boxes
    again = collect_voxels(load_warehouse(), 1, np.random.default_rng(0))
    np.testing.assert_array_equal(again.features, data.features[data.map_ids == 0])


def test_fit_predict_cells(data):
    model = AffordanceClassifier().fit(data.features, data.labels)
    assert model.is_fitted
    mine = data.map_ids == 0
    cells = np.column_stack([(data.cell_ids[mine] % 144) // 12, data.cell_ids[mine] % 12])
    p = model.predict_cells(data.features[mine], cells, (12, 12))
    assert p.shape == (12, 12, 4)
    seen = np.zeros((12, 12), dtype=bool)
    seen[cells[:, 0], cells[:, 1]] = True
    assert np.isnan(p[~seen]).all() and np.isfinite(p[seen]).all()
    assert ((p[seen] >= 0) & (p[seen] <= 1)).all()
    truth = np.zeros((12, 12, 4), dtype=bool)
    truth[cells[:, 0], cells[:, 1]] = data.labels[mine]
    assert ((p[seen] >= 0.5) == truth[seen]).mean() > 0.9


def test_constant_direction_and_errors(data):
    model = AffordanceClassifier()
    with pytest.raises(InputError, match="not trained"):
        model.predict_proba(data.features)
    with pytest.raises(InputError, match="not trained"):
        model.predict_cells(data.features, np.zeros((len(data.features), 2), int), (12, 12))
    labels = data.labels.copy()
    labels[:, 0] = False
    model.fit(data.features, labels)
    p = model.predict_proba(data.features[:5])
    assert (p[:, 0] == 0.0).all()
    with pytest.raises(InputError):
        model.predict_proba(data.features[:, :-1])
    with pytest.raises(InputError):
        model.predict_proba(np.full_like(data.features[:2], np.nan))
    with pytest.raises(InputError):
        model.predict_cells(data.features[:2], np.array([[0, 0], [12, 0]]), (12, 12))
    with pytest.raises(InputError):
        model.predict_cells(data.features[:2], np.array([[0, 0]]), (12, 12))
    with pytest.raises(InputError):
        AffordanceClassifier().fit(data.features, data.labels[:-1])
    with pytest.raises(InputError):
        AffordanceClassifier().fit(data.features[:0], data.labels[:0])


def test_small_evaluation():
    walled = dataclasses.replace(load_warehouse(), sensor_kind="scanner")  # quick, exact grid
    border_only = dataclasses.replace(walled, wall_segments=(0, 0), box_row_share=0.0)
    easy = evaluate(n_maps=6, folds=3, seed=0, spec=border_only)
    ev = evaluate(n_maps=6, folds=3, seed=0, spec=walled)
    for scores in (easy.precision, easy.recall):
        assert scores is not None and (scores > 0.85).all()  # walls only on the border
    for scores in (ev.precision, ev.recall, ev.grouped_precision, ev.grouped_recall):
        assert scores is not None and scores.shape == (4,)
        # interior wall blocks look like boxes: the thesis's ambiguity, not a give-away
        assert (scores > 0.5).all() and (scores < 0.97).all()
    assert float(ev.precision.mean()) < float(easy.precision.mean())
    assert ev.n_maps == 6 and ev.n_cells > 50 and ev.n_voxels >= ev.n_cells
    assert ev.coverage == 1.0 and ev.seconds > 0
    table = ev.table()
    assert all(name in table for name in ("up", "down", "left", "right", "precision"))


@pytest.mark.parametrize("kwargs", [{"folds": 1}, {"n_maps": 0}])
def test_bad_evaluation_settings(kwargs):
    with pytest.raises(InputError):
        evaluate(**kwargs)


def test_classifier_settings_are_validated(data):
    rng = np.random.default_rng(0)
    for bad in (0, -1.0, float("nan")):
        with pytest.raises(InputError, match=r"C \(inverse regularisation strength\) must be a"):
            AffordanceClassifier(C=bad)
    with pytest.raises(InputError, match=r"C \(inverse regularisation strength\) must be a"):
        evaluate(n_maps=2, folds=2, C=0)
    with pytest.raises(InputError, match="spec must be the warehouse world, a WarehouseSpec"):
        collect_voxels("warehouse", 1, rng)  # type: ignore[arg-type]
    with pytest.raises(InputError, match=r"rng must be a numpy.random.Generator .*got int"):
        collect_voxels(load_warehouse(), 1, 0)  # type: ignore[arg-type]
    model = AffordanceClassifier().fit(data.features, data.labels)
    cells = np.zeros((2, 2), dtype=int)
    with pytest.raises(InputError, match="map_shape rows must be a positive integer, got 0"):
        model.predict_cells(data.features[:2], cells, (0, 12))
    with pytest.raises(InputError, match=r"map_shape must be \(rows, cols\)"):
        model.predict_cells(data.features[:2], cells, 12)  # type: ignore[arg-type]
