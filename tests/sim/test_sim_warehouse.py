"""The grid warehouse: maps, generator, and physics ground truth against the rule."""

import numpy as np
import pytest

from probaff.errors import ConfigError, InputError
from probaff.sim.warehouse import (
    WarehouseMap,
    generate_map,
    physics_affordances,
    push_box,
    rule_affordances,
)
from probaff.sim.warehouse_config import load_warehouse


@pytest.fixture(scope="module")
def spec():
    return load_warehouse()


def test_generated_maps(spec):
    rng = np.random.default_rng(0)
    counts = [generate_map(spec, rng).movable.sum() for _ in range(50)]  # boxes, not walls
    assert min(counts) >= 10 and max(counts) <= 30
    big = generate_map(spec, rng, shape=(100, 100))
    assert big.shape == (100, 100) and 500 < big.movable.sum() < 2500
    a = generate_map(spec, np.random.default_rng(3))
    b = generate_map(spec, np.random.default_rng(3))
    np.testing.assert_array_equal(a.occupancy, b.occupancy)
    np.testing.assert_array_equal(a.walls, b.walls)


def test_physics_ground_truth_follows_the_rule(spec):
    rng = np.random.default_rng(1)
    for _ in range(2):  # tests/sim/test_sim_warehouse_walls.py checks one more
        m = generate_map(spec, rng)
        np.testing.assert_array_equal(physics_affordances(spec, m), rule_affordances(m))


def test_two_boxes_in_a_row_and_walls_block(spec):
    m = WarehouseMap.from_boxes((4, 4), [(1, 1), (1, 2), (0, 3)])
    right = push_box(spec, m, (1, 1), 3)
    assert not right.moved and right.robot_lag > 0.5  # two in a row: the robot stalls
    left = push_box(spec, m, (1, 1), 2)
    assert left.moved and abs(left.displacement[0] + 1.0) < 0.05  # one cell to -x
    up = push_box(spec, m, (0, 3), 0)
    assert not up.moved and np.hypot(*up.displacement) < 0.03  # closes its 2 cm gap, no more
    rule = rule_affordances(m)
    assert rule[1, 1].tolist() == [True, True, True, False]
    assert rule[0, 3].tolist() == [False, True, True, False]  # walls above and right


def test_cell_geometry(spec):
    m = WarehouseMap.from_boxes((3, 5), [(0, 0)])
    np.testing.assert_allclose(m.cell_centre(np.array([0, 0])), [0.5, 2.5])
    np.testing.assert_array_equal(m.cell_of(np.array([[0.5, 2.5], [4.9, 0.1]])), [[0, 0], [2, 4]])
    moved = m.moved((0, 0), 1)
    assert moved.occupancy[1, 0] and not moved.occupancy[0, 0]


def test_bad_maps(spec):
    with pytest.raises(InputError, match="outside the walls"):
        WarehouseMap.from_boxes((12, 12), [(3, 12)])
    with pytest.raises(InputError, match="two boxes in cell"):
        WarehouseMap.from_boxes((12, 12), [(3, 4), (3, 4)])
    with pytest.raises(InputError, match="no box"):
        push_box(spec, WarehouseMap.from_boxes((4, 4), [(1, 1)]), (2, 2), 0)
    with pytest.raises(ConfigError, match="cannot place"):
        generate_map(spec, np.random.default_rng(0), shape=(2, 2), n_boxes=(4, 4))
    with pytest.raises(InputError, match="not free"):
        WarehouseMap.from_boxes((4, 4), [(0, 0)]).moved((0, 0), 0)
