"""Interior wall blocks of the warehouse: built in the world, seen like boxes, never pushable.

Covers probaff.sim.warehouse (wall blocks, generated layouts, the rule and the physics next to
walls) and probaff.sim.warehouse_config (the ``interior_walls`` and ``box_rows`` sections).
"""

import dataclasses

import numpy as np
import pytest
import yaml

from probaff.errors import ConfigError, InputError, ProbaffError
from probaff.sim.depth import DepthSensor, obstacle_bounds
from probaff.sim.warehouse import (
    WarehouseMap,
    generate_map,
    physics_affordances,
    push_box,
    rule_affordances,
)
from probaff.sim.warehouse_config import load_warehouse
from probaff.sim.world_files import worlds_dir

UP, DOWN, LEFT, RIGHT = range(4)


@pytest.fixture(scope="module")
def spec():
    return load_warehouse()


def _write(tmp_path, raw):
    path = tmp_path / "warehouse.yaml"
    path.write_text(yaml.safe_dump(raw))
    return path


@pytest.fixture
def raw():
    return yaml.safe_load((worlds_dir() / "warehouse.yaml").read_text())


def _adjacent_boxes(maps):
    """Mean number of 4-adjacent box pairs per map."""
    return np.mean(
        [
            (m.movable[1:] & m.movable[:-1]).sum() + (m.movable[:, 1:] & m.movable[:, :-1]).sum()
            for m in maps
        ]
    )


def test_the_world_file_builds_interior_walls(spec):
    assert spec.wall_segments == (3, 5) and spec.wall_length == (2, 5)
    assert spec.wall_layouts == ("line", "corner") and spec.box_row_share == 0.5
    rng = np.random.default_rng(0)
    maps = [generate_map(spec, rng) for _ in range(40)]
    for m in maps:
        assert not (m.walls & ~m.occupancy).any()  # every wall block is a block
        assert 10 <= m.movable.sum() <= 30  # the box count leaves the walls out
        assert 2 <= m.walls.sum() <= 25  # 3..5 segments of 2..5 blocks, clipped, may cross
        assert (~m.occupancy).any()
    mean_walls = np.mean([m.walls.sum() for m in maps])
    assert 8 < mean_walls < 16
    # Boxes stand in rows: far more 4-adjacent box pairs than uniform placement gives.
    uniform = dataclasses.replace(spec, box_row_share=0.0)
    scattered = [generate_map(uniform, np.random.default_rng(i)) for i in range(40)]
    assert _adjacent_boxes(maps) > 1.5 * _adjacent_boxes(scattered)
    # Some boxes stand against a wall block.
    against = sum(
        ((m.movable[1:] & m.walls[:-1]) | (m.movable[:-1] & m.walls[1:])).sum() for m in maps
    )
    assert against > 20
    a, b = (
        generate_map(spec, np.random.default_rng(5)),
        generate_map(spec, np.random.default_rng(5)),
    )
    np.testing.assert_array_equal(a.occupancy, b.occupancy)
    np.testing.assert_array_equal(a.walls, b.walls)
    big = generate_map(spec, rng, shape=(60, 60))
    assert 200 < big.walls.sum() < 500  # segments scale with the area (25x)


def test_layouts_are_lines_or_corners(spec):
    line = dataclasses.replace(
        spec, wall_segments=(1, 1), wall_length=(4, 4), wall_layouts=("line",), boxes=(0, 0)
    )
    corner = dataclasses.replace(line, wall_layouts=("corner",))
    rng = np.random.default_rng(1)
    for _ in range(30):
        w = generate_map(line, rng).walls
        cells = np.argwhere(w)
        assert 1 <= len(cells) <= 4
        assert len(set(cells[:, 0])) == 1 or len(set(cells[:, 1])) == 1  # one row or one column
    turned = 0
    for _ in range(30):
        cells = np.argwhere(generate_map(corner, rng).walls)
        rows, cols = len(set(cells[:, 0])), len(set(cells[:, 1]))
        turned += rows > 1 and cols > 1
    assert turned > 15  # an L spans rows and columns unless the border clipped it


def test_wall_blocks_look_like_boxes_to_the_camera(spec):
    box = WarehouseMap.from_boxes((6, 6), [(2, 3), (4, 1)])
    wall = WarehouseMap.from_boxes((6, 6), [(4, 1)], walls=[(2, 3)])
    lo_b, hi_b = obstacle_bounds(spec, box)
    lo_w, hi_w = obstacle_bounds(spec, wall)
    np.testing.assert_array_equal(lo_b, lo_w)
    np.testing.assert_array_equal(hi_b, hi_w)
    k = [tuple(c) for c in wall.boxes.tolist()].index((2, 3))
    np.testing.assert_allclose(hi_w[k] - lo_w[k], [spec.box_size, spec.box_size, spec.box_height])
    assert spec.sensor_kind == "camera"
    where = box.cell_centre(np.array([2, 1]))
    scans = [DepthSensor(spec, m).scan(where, np.random.default_rng(7)) for m in (box, wall)]
    assert len(scans[0].points) > 500
    np.testing.assert_array_equal(scans[0].points, scans[1].points)  # the same depth, noise too
    np.testing.assert_array_equal(scans[0].ends, scans[1].ends)
    # and the points of that cell cover the box's whole footprint face
    cell = wall.cell_of(scans[1].points[:, :2])
    face = scans[1].points[(cell == [2, 3]).all(-1)]
    assert len(face) > 50 and face[:, 2].max() > 1.2  # up to where the tilted view ends


def test_ground_truth_next_to_interior_walls(spec):
    # .  .  .  .  .
    # .  B  W  B  .      B(1,1) left of a wall, B(1,3) right of it
    # .  B  W  .  .      B(2,1) against the wall and under a box
    # .  .  B  .  .      B(3,2) under a wall block
    m = WarehouseMap.from_boxes((5, 5), [(1, 1), (1, 3), (2, 1), (3, 2)], walls=[(1, 2), (2, 2)])
    rule = rule_affordances(m)
    assert rule[1, 1].tolist() == [True, False, True, False]  # box below, wall right
    assert rule[1, 3].tolist() == [True, True, False, True]  # wall left
    assert rule[2, 1].tolist() == [False, True, True, False]  # box above, wall right
    assert rule[3, 2].tolist() == [False, True, True, True]  # wall above
    assert not rule[m.walls].any()  # wall blocks are never pushable
    np.testing.assert_array_equal(physics_affordances(spec, m), rule)
    into = push_box(spec, m, (1, 3), LEFT)
    assert not into.moved and np.hypot(*into.displacement) < 0.05  # closes its 4 cm gap
    wall = push_box(spec, m, (2, 2), RIGHT)
    assert not wall.moved and not wall.displacement.any() and wall.robot_lag > 0.5
    away = push_box(spec, m, (1, 3), RIGHT)
    assert away.moved and abs(away.displacement[0] - 1.0) < 0.05
    moved = m.moved((1, 3), RIGHT)
    assert moved.walls[1, 2] and moved.walls[2, 2] and moved.movable[1, 4]
    with pytest.raises(InputError, match=r"cell \(1, 2\) holds a wall block, which never moves"):
        m.moved((1, 2), UP)


def test_physics_agrees_with_the_rule_on_generated_maps(spec):
    rng = np.random.default_rng(2)
    m = generate_map(spec, rng)
    assert m.walls.any()
    np.testing.assert_array_equal(physics_affordances(spec, m), rule_affordances(m))


def test_bad_wall_blocks_are_refused():
    with pytest.raises(InputError, match=r"walls\[1\]: wall block at cell \(4, 0\) lies outside"):
        WarehouseMap.from_boxes((4, 4), [(0, 0)], walls=[(1, 1), (4, 0)])
    with pytest.raises(InputError, match=r"wall block on the box at cell \(1, 1\).*move the wall"):
        WarehouseMap.from_boxes((4, 4), [(1, 1)], walls=[(1, 1)])
    with pytest.raises(InputError, match=r"two wall blocks in cell \(2, 2\)"):
        WarehouseMap.from_boxes((4, 4), [], walls=[(2, 2), (2, 2)])
    with pytest.raises(InputError, match=r"walls\[0\]\[1\] must be an integer"):
        WarehouseMap.from_boxes((4, 4), [], walls=[(2, "a")])
    occ = np.zeros((3, 3), dtype=bool)
    walls = occ.copy()
    walls[0, 1] = True
    with pytest.raises(InputError, match=r"walls marks cell \(0, 1\), which occupancy leaves"):
        WarehouseMap(occ, 1.0, walls)
    with pytest.raises(InputError, match="walls must be a bool array of the occupancy's shape"):
        WarehouseMap(occ, 1.0, np.zeros((2, 3), dtype=bool))
    assert issubclass(InputError, ProbaffError)


def test_bad_wall_settings_name_the_setting(spec, tmp_path, raw):
    raw["interior_walls"]["blocks"] = [[3, 4], [12, 0]]
    with pytest.raises(ConfigError, match=r"interior_walls\.blocks\[1\] \[12, 0\] lies outside"):
        load_warehouse(_write(tmp_path, raw))
    raw["interior_walls"]["blocks"] = [[3, 4], [3, 4]]
    with pytest.raises(ConfigError, match=r"blocks\[1\] repeats the wall block \[3, 4\]"):
        load_warehouse(_write(tmp_path, raw))
    raw["interior_walls"]["blocks"] = []
    raw["interior_walls"]["layouts"] = ["line", "zigzag"]
    with pytest.raises(ConfigError, match=r"interior_walls\.layouts must be .* line, corner"):
        load_warehouse(_write(tmp_path, raw))
    raw["interior_walls"]["layouts"] = ["line"]
    raw["interior_walls"]["length"] = [0, 3]
    with pytest.raises(ConfigError, match=r"interior_walls\.length must be at least 1 block"):
        load_warehouse(_write(tmp_path, raw))
    raw["interior_walls"]["length"] = [2, 3]
    raw["box_rows"]["share"] = 1.5
    with pytest.raises(ConfigError, match=r"box_rows\.share must be a probability"):
        load_warehouse(_write(tmp_path, raw))
    with pytest.raises(ConfigError, match=r"wall_blocks\[0\] \[12, 3\] lies outside the 12 x 12"):
        dataclasses.replace(spec, wall_blocks=((12, 3),))
    with pytest.raises(ConfigError, match=r"WarehouseSpec\.box_row_share must be a share"):
        dataclasses.replace(spec, box_row_share=-0.1)
    fixed = dataclasses.replace(spec, wall_blocks=((10, 10),))
    with pytest.raises(InputError, match=r"blocks holds \[10, 10\], outside the requested 8 x 8"):
        generate_map(fixed, np.random.default_rng(0), shape=(8, 8))
    with pytest.raises(ConfigError, match=r"cannot place .* with .* wall blocks"):
        generate_map(spec, np.random.default_rng(0), shape=(3, 3), n_boxes=(9, 9))


def test_yaml_round_trip(spec, tmp_path, raw):
    # The world file read, written back and read again gives the same world.
    assert load_warehouse(_write(tmp_path, raw)) == spec
    # A fixed layout written in YAML stands in every generated map, exactly.
    rng = np.random.default_rng(3)
    layout = generate_map(spec, rng)
    raw["interior_walls"] = {
        "segments": [0, 0],
        "length": [1, 1],
        "layouts": ["line"],
        "blocks": np.argwhere(layout.walls).tolist(),
    }
    raw["box_rows"] = {"share": 0.0, "length": [1, 1]}
    fixed = load_warehouse(_write(tmp_path, raw))
    assert fixed.wall_blocks == tuple(map(tuple, np.argwhere(layout.walls).tolist()))
    for seed in range(3):
        m = generate_map(fixed, np.random.default_rng(seed))
        np.testing.assert_array_equal(m.walls, layout.walls)
        assert not (m.movable & m.walls).any()
    # Without the sections the warehouse has border walls only.
    del raw["interior_walls"], raw["box_rows"]
    bare = load_warehouse(_write(tmp_path, raw))
    assert bare.wall_segments == (0, 0) and bare.wall_blocks == ()
    assert not generate_map(bare, np.random.default_rng(0)).walls.any()
