"""The occupancy grid: exact ray traversal, states, per-cell summaries and frontiers."""

import dataclasses

import numpy as np
import pytest

from probaff.errors import InputError
from probaff.perception import FREE_SPACE, OCCUPIED, UNKNOWN, OccupancyGrid
from probaff.sim.depth import DepthScan, DepthSensor
from probaff.sim.warehouse import WarehouseMap
from probaff.sim.warehouse_config import load_warehouse


@pytest.fixture(scope="module")
def spec():
    """The idealised scanner, whose rays reach the walls (the analytic cases below)."""
    return dataclasses.replace(load_warehouse(), sensor_kind="scanner")


def _scan(origin, ends, hits):
    ends = np.asarray(ends, dtype=float)
    return DepthScan(
        points=np.empty((0, 3)),
        origin=np.array([*origin, 1.0]),
        azimuths=np.zeros(len(ends)),
        ends=ends,
        hits=np.asarray(hits),
    )


def test_single_ray_marks_the_crossed_sub_cells():
    g = OccupancyGrid((4, 4))
    g.update(_scan([0.5, 0.5], [[2.52, 0.5]], [True]))
    st = g.state
    row = 14  # y = 0.5 lies in the second sub-cell row from the bottom
    assert (st[row, 2:10] == FREE_SPACE).all()  # x from 0.5 to 2.48 (stops 0.04 short)
    assert st[row, 10] == OCCUPIED  # the hit, 0.02 beyond 2.52
    assert (st[row, :2] == UNKNOWN).all() and (st[row, 11:] == UNKNOWN).all()
    assert (np.delete(st, row, 0) == UNKNOWN).all()
    assert g.passes.sum() == 8 and g.hits.sum() == 1


def test_diagonal_ray_is_traversed_exactly():
    g = OccupancyGrid((2, 2), resolution=0.5)
    g.update(_scan([0.25, 0.25], [[1.75, 1.75]], [False]))  # a miss: traced to its end
    np.testing.assert_array_equal(g.passes, np.eye(4, dtype=int)[::-1])
    assert g.hits.sum() == 0


def test_majority_decides_and_misses_leave_no_hit():
    g = OccupancyGrid((2, 2))
    g.update(_scan([0.1, 1.1], [[1.52, 1.1]], [True]))  # free to 1.48, hit at 1.54
    g.update(_scan([0.1, 1.1], [[1.9, 1.1]], [False]))
    g.update(_scan([0.1, 1.1], [[1.9, 1.1]], [False]))
    j = 6  # x in [1.5, 1.75)
    assert g.hits[3, j] == 1 and g.passes[3, j] == 2 and g.state[3, j] == FREE_SPACE


def _one_box_grid(spec):
    """The grid after one scan from cell (6, 5) of a 12 x 12 map with one box, at (6, 8)."""
    m = WarehouseMap.from_boxes((12, 12), [(6, 8)])
    scan = DepthSensor(spec, m).scan(m.cell_centre(np.array([6, 5])), np.random.default_rng(0))
    g = OccupancyGrid(m.shape, m.cell_size)
    g.update(scan)
    return g


def test_one_scan_of_one_box(spec):
    g = _one_box_grid(spec)
    f = g.cell_fractions()
    assert f.shape == (12, 12, 3)
    np.testing.assert_allclose(f.sum(-1), 1.0)
    states = g.cell_states()
    assert states[6, 8] == OCCUPIED and states[6, 5] == FREE_SPACE
    assert states[6, 9] == UNKNOWN  # in the box's shadow
    assert f[6, 8, 1] > 0 and f[6, 8, 0] == 0.0  # the face seen, the inside never
    # cells along the walls are free, not occupied: wall hits fall outside the grid
    assert f[..., 1].sum() == f[6, 8, 1]
    assert states[0, 5] == FREE_SPACE and states[6, 0] == FREE_SPACE


def test_frontiers(spec):
    g = _one_box_grid(spec)
    fr = g.frontier()
    assert fr.shape == g.fine_shape and fr.any()
    st = g.state
    assert (st[fr] == FREE_SPACE).all()
    cell_fr = g.cell_frontier()
    assert cell_fr[5, 9] or cell_fr[7, 9]  # beside the shadow behind the box
    assert not cell_fr[6, 5]


@pytest.mark.parametrize(
    "kwargs",
    [
        {"resolution": 0.3},
        {"resolution": 0.0},
        {"cell_size": -1.0},
        {"resolution": 2.0},
        {"margin": float("nan")},
    ],
)
def test_bad_settings(kwargs):
    with pytest.raises(InputError):
        OccupancyGrid((4, 4), **kwargs)


def test_bad_scan():
    g = OccupancyGrid((4, 4))
    with pytest.raises(InputError):
        g.update(_scan([0.5, 0.5], [[np.nan, 0.5]], [True]))
    with pytest.raises(InputError):
        g.update(_scan([0.5, 0.5], [[1.0, 0.5]], [True, False]))


def test_one_camera_scan_of_one_box():
    spec = load_warehouse()  # the head camera: 4.5 m range, floor returns prove free space
    m = WarehouseMap.from_boxes((12, 12), [(6, 8)])
    scan = DepthSensor(spec, m).scan(m.cell_centre(np.array([6, 5])), np.random.default_rng(0))
    g = OccupancyGrid(m.shape, m.cell_size)
    g.update(scan)
    states = g.cell_states()
    assert states[6, 8] == OCCUPIED  # the box's face, 2.5 m ahead
    assert states[6, 9] == UNKNOWN  # in its shadow
    assert (states[6, 6:8] == FREE_SPACE).all() and (states[5:8, 4] == FREE_SPACE).all()
    assert (states[0] == UNKNOWN).all()  # the walls are beyond the camera's range
    assert (states == OCCUPIED).sum() == 1
