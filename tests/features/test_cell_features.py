"""Per-voxel features of an explored warehouse: shapes, meaning of columns, bad input."""

import dataclasses

import numpy as np
import pytest

from probaff.errors import InputError
from probaff.features.cells import HMP_SCALES, cell_features, feature_names
from probaff.perception import OccupancyGrid, explore
from probaff.sim.warehouse import WarehouseMap, generate_map
from probaff.sim.warehouse_config import load_warehouse


@pytest.fixture(scope="module")
def spec():
    """The idealised scanner: its grid is exact, so voxels lie on boxes only."""
    return dataclasses.replace(load_warehouse(), sensor_kind="scanner")


@pytest.fixture(scope="module")
def random_run(spec):
    rng = np.random.default_rng(3)
    m = generate_map(spec, rng)
    return m, explore(spec, m, np.argwhere(~m.occupancy)[0], rng)


@pytest.fixture(scope="module")
def wall_box(spec):
    m = WarehouseMap.from_boxes((6, 6), [(0, 2), (3, 3)])
    run = explore(spec, m, (5, 0), np.random.default_rng(0))
    return cell_features(run.points, run.grid)


def test_names_and_groups_tile_the_columns():
    names, groups = feature_names()
    assert len(names) == len(set(names)) == 43
    cols = np.concatenate([np.arange(43)[s] for s in groups.values()])
    np.testing.assert_array_equal(cols, np.arange(43))
    assert [f"hmp_{h:g}" for h in HMP_SCALES] == ["hmp_0.5", "hmp_0.25"]


def test_shapes_and_finite(random_run):
    m, run = random_run
    vox = cell_features(run.points, run.grid)
    x = vox.features.values
    assert x.shape == (len(vox.cells), 43) and np.isfinite(x).all()
    assert set(vox.layers.tolist()) <= {0, 1}
    assert m.occupancy[vox.cells[:, 0], vox.cells[:, 1]].all()  # voxels only on boxes
    keys = vox.cells[:, 0] * 100 + vox.cells[:, 1] * 2 + vox.layers
    assert (np.diff(keys) > 0).all()  # row-major, then by layer
    np.testing.assert_allclose(vox.features.select("own").sum(1), 1.0)
    access = vox.features.select("access").reshape(-1, 4, 3)
    np.testing.assert_allclose(access.sum(-1), 1.0)
    for h in HMP_SCALES:
        s = vox.features.select(f"hmp_{h:g}").sum(1)
        assert np.all(np.isclose(s, 1.0) | np.isclose(s, 0.0))
    pair = vox.features.select("pairwise")
    assert ((pair >= 0) & (pair <= 1)).all()
    assert (x[:, vox.features.columns("saliency")] >= -1e-12).all()


def test_columns_mean_what_they_say(wall_box):
    vox = wall_box
    f, names = vox.features, vox.features.names
    col = {n: i for i, n in enumerate(names)}
    top = (vox.cells[:, 0] == 0) & (vox.cells[:, 1] == 2)
    mid = (vox.cells[:, 0] == 3) & (vox.cells[:, 1] == 3)
    assert top.sum() == 2 and mid.sum() == 2
    x = f.values
    assert (x[top, col["up_occupied"]] == 1.0).all() and (x[top, col["pair_up"]] == 1.0).all()
    for rows, dirs in ((top, ("down", "left", "right")), (mid, ("up", "down", "left", "right"))):
        for d in dirs:
            assert (x[rows, col[f"{d}_free"]] >= 0.75).all()
            assert (x[rows, col[f"{d}_occupied"]] == 0.0).all()
    np.testing.assert_array_equal(np.sort(vox.layers[mid]), [0, 1])
    # the robot saw the free-standing box mostly from above (up) and from the left
    hmp = x[mid][:, f.columns("hmp_0.5")]
    assert (hmp[:, [0, 2]] > 0).all()
    assert (x[mid, col["log_count"]] > np.log(50)).all()
    assert (np.abs(x[mid][:, f.columns("centroid")]) < 0.5).all()
    assert (x[mid][:, f.columns("span")][:, :2] > 0.8).all()  # faces cover the footprint


def test_face_normals_and_saliency_of_a_plane():
    grid = OccupancyGrid((3, 3))
    grid.hits[4:8, 4:8] = 1  # cell (1, 1) occupied: x in [1, 2], y in [1, 2]
    y, z = np.meshgrid(np.linspace(1.05, 1.95, 30), np.linspace(0.1, 0.9, 30))
    rng = np.random.default_rng(0)
    face = np.column_stack([1.98 + 0.001 * rng.standard_normal(y.size), y.ravel(), z.ravel()])
    vox = cell_features(face, grid, n_layers=1)
    assert vox.cells.tolist() == [[1, 1]]
    f = vox.features
    np.testing.assert_allclose(f.select("normal")[0], [1.0, 0.0, 0.0], atol=0.01)
    for h in HMP_SCALES:
        np.testing.assert_allclose(f.select(f"hmp_{h:g}")[0], [0, 0, 0, 1, 0])  # right (+x)
    scatter, linear, planar = f.select("saliency")[0]
    assert planar > 0.5 * scatter and linear < 0.3 * scatter  # a near-square plane
    np.testing.assert_allclose(f.select("centroid")[0], [0.48, 0.0, 0.0], atol=0.01)
    np.testing.assert_allclose(f.select("span")[0], [0.0, 0.9, 0.8], atol=0.01)
    assert f.select("count")[0, 0] == pytest.approx(np.log1p(900))
    np.testing.assert_allclose(f.select("own")[0], [0.0, 1.0, 0.0])
    np.testing.assert_allclose(f.select("access")[0].reshape(4, 3), [[0, 0, 1]] * 4)
    np.testing.assert_allclose(f.select("pairwise")[0], 0.0)


def test_empty_cloud_gives_no_voxels():
    vox = cell_features(np.empty((0, 3)), OccupancyGrid((4, 4)))
    assert vox.features.values.shape == (0, 43) and vox.cells.shape == (0, 2)


@pytest.mark.parametrize("points", [np.zeros((5, 2)), np.full((5, 3), np.nan), np.zeros(3)])
def test_bad_points(points):
    with pytest.raises(InputError):
        cell_features(points, OccupancyGrid((4, 4)))


@pytest.mark.parametrize("kwargs", [{"min_points": 2}, {"n_layers": 0}, {"floor_height": -1.0}])
def test_bad_settings(kwargs):
    with pytest.raises(InputError):
        cell_features(np.zeros((5, 3)), OccupancyGrid((4, 4)), **kwargs)
