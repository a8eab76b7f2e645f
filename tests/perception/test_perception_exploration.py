"""Frontier-based exploration: coverage of the reachable cells, pockets, determinism."""

import dataclasses

import numpy as np
import pytest

from probaff.errors import InputError
from probaff.grid import DIRECTION_OFFSETS
from probaff.perception import FREE_SPACE, OCCUPIED, UNKNOWN, explore, grid_distances
from probaff.sim.warehouse import WarehouseMap, generate_map
from probaff.sim.warehouse_config import load_warehouse


@pytest.fixture(scope="module")
def spec():
    """The idealised scanner, whose exploration guarantees are exact (see explore)."""
    return dataclasses.replace(load_warehouse(), sensor_kind="scanner")


def _next_to(mask):
    h, w = mask.shape
    padded = np.pad(mask, 1)
    return np.any(
        [padded[1 + dr : 1 + dr + h, 1 + dc : 1 + dc + w] for dr, dc in DIRECTION_OFFSETS], 0
    )


def test_grid_distances():
    passable = np.array([[1, 1, 1], [0, 0, 1], [1, 1, 1]], dtype=bool)
    d = grid_distances(passable, (0, 0))
    np.testing.assert_array_equal(d, [[0, 1, 2], [-1, -1, 3], [6, 5, 4]])
    assert grid_distances(~passable, (1, 0))[0, 0] == -1


def _explored(spec, seed):
    """A generated map explored from a random free cell: map, start, run, states, reachable."""
    rng = np.random.default_rng(seed)
    m = generate_map(spec, rng)
    free = np.argwhere(~m.occupancy)
    start = free[rng.integers(len(free))]
    run = explore(spec, m, start, rng)
    reach = grid_distances(~m.occupancy, tuple(start)) >= 0
    return m, start, run, run.grid.cell_states(), reach


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_every_reachable_cell_is_observed(spec, seed):
    m, start, run, states, reach = _explored(spec, seed)
    assert (states[reach] == FREE_SPACE).all()
    assert (states[_next_to(reach) & m.occupancy] == OCCUPIED).all()
    assert not (states[m.occupancy] == FREE_SPACE).any()
    assert not (states[~m.occupancy] == OCCUPIED).any()
    # the robot only stood on reachable cells, starting at the start, one scan per cell
    np.testing.assert_array_equal(run.cells[0], start)
    assert reach[run.cells[:, 0], run.cells[:, 1]].all()
    assert len(np.unique(run.cells, axis=0)) == len(run.cells)
    assert run.path_length >= len(run.cells) - 1
    assert run.points.ndim == 2 and run.points.shape[1] == 3 and np.isfinite(run.points).all()


def test_enclosed_pockets_stay_unseen(spec):
    ring = [(r, c) for r in range(4, 7) for c in range(4, 7) if (r, c) != (5, 5)]
    corner = [(0, 1), (1, 0), (1, 1)]
    boxed_in = [(9, 9)] + [(r, c) for r in range(8, 11) for c in range(8, 11) if (r, c) != (9, 9)]
    m = WarehouseMap.from_boxes((12, 12), ring + corner + boxed_in)
    run = explore(spec, m, (11, 0), np.random.default_rng(0))
    states = run.grid.cell_states()
    f = run.grid.cell_fractions()
    for cell in [(5, 5), (0, 0), (9, 9)]:  # free pockets and a box inside a ring
        assert states[cell] == UNKNOWN and f[cell][2] == 1.0
    for cell in ring + corner + boxed_in[1:]:
        assert states[cell] == OCCUPIED
    # no point of any scan lies inside the pockets
    xy = run.points[:, :2]
    for r, c in [(5, 5), (0, 0), (9, 9)]:
        lo = m.cell_centre(np.array([r, c])) - 0.45
        assert not np.all((xy > lo) & (xy < lo + 0.9), axis=1).any()
    # every other free cell is known
    others = ~m.occupancy
    others[5, 5] = others[0, 0] = False
    assert (states[others] == FREE_SPACE).all()


def test_a_box_hidden_from_the_start_is_found(spec):
    # a box right behind another one, as seen from the start, is seen from elsewhere
    m = WarehouseMap.from_boxes((6, 6), [(2, 2), (2, 3)])
    run = explore(spec, m, (2, 0), np.random.default_rng(0))
    assert run.grid.cell_states()[2, 3] == OCCUPIED
    assert len(run.cells) > 1


def test_deterministic(spec):
    m = generate_map(spec, np.random.default_rng(5))
    start = np.argwhere(~m.occupancy)[0]
    a = explore(spec, m, start, np.random.default_rng(9))
    b = explore(spec, m, start, np.random.default_rng(9))
    np.testing.assert_array_equal(a.points, b.points)
    np.testing.assert_array_equal(a.cells, b.cells)


@pytest.mark.parametrize("start", [(0, 1), (-1, 0), (0, 12), (0.5, 2.0), (1, 2, 3)])
def test_bad_starts(spec, start):
    m = WarehouseMap.from_boxes((12, 12), [(0, 1)])
    with pytest.raises(InputError):
        explore(spec, m, np.array(start), np.random.default_rng(0))


def test_camera_exploration_knows_the_reachable_cells():
    # the head camera (noisy, registered views, 4.5 m range) on 8 x 8 maps, to keep it quick
    spec = dataclasses.replace(load_warehouse(), rows=8, cols=8, boxes=(8, 14))
    phantoms = 0
    for seed in range(3):
        m, _, _, states, reach = _explored(spec, seed)
        assert not (states[reach] == UNKNOWN).any()
        assert (states[_next_to(reach) & m.occupancy] == OCCUPIED).all()
        assert not (states[m.occupancy] == FREE_SPACE).any()
        phantoms += int((states[~m.occupancy] == OCCUPIED).sum())
    assert phantoms <= 3  # stray hits by the walls (2 here), of about 150 free cells
