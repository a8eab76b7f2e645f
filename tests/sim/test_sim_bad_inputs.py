"""Bad input to the simulator ends in a ProbaffError naming the argument, before pymunk sees it.

pymunk wraps Chipmunk, a C library: a negative mass or friction aborts the whole Python process
there, so these tests check that validation raises first (pymunk is replaced by a tripwire
where a bad value would reach it). The shared wording of these checks is probaff.sim.inputs.
"""

import dataclasses
import math

import numpy as np
import pymunk
import pytest

from probaff.errors import ConfigError, InputError
from probaff.sim import (
    DepthCamera,
    PushSimulator,
    SceneInstance,
    SideViewScene,
    head_views,
    load_catalogue,
    load_sideview,
    load_tabletop,
    load_warehouse,
    scan_views,
    simulate_push,
    simulate_sideview,
)
from probaff.sim import tabletop as tabletop_module
from probaff.sim import warehouse as warehouse_module
from probaff.sim.depth import DepthSensor
from probaff.sim.friction import add_sliding_body
from probaff.sim.geometry import push_frame_effect
from probaff.sim.primitives import PrimitiveScene
from probaff.sim.pusher import TrackedPusher
from probaff.sim.runner import straight_path, trapezoid_progress
from probaff.sim.sensing import object_cloud, scan_scene, table_cloud
from probaff.sim.sideview import simulate_rest
from probaff.sim.skills import plan_skills


@pytest.fixture(scope="module")
def world():
    return load_tabletop()


@pytest.fixture(scope="module")
def sim():
    return PushSimulator("single_free")


@pytest.fixture
def scene(world):
    book = load_catalogue()["book"]
    return SceneInstance.nominal(
        [book], [[0.0, 0.0, 0.0]], [-0.13, 0.0], 0.0, 0.15, world.physics.friction_grid
    )


@pytest.fixture
def no_pymunk(monkeypatch):
    """Make any pymunk space built by the tabletop fail the test: validation must come first."""

    def tripwire(*args, **kwargs):
        raise AssertionError("an invalid scene reached pymunk")

    monkeypatch.setattr(tabletop_module.pymunk, "Space", tripwire)


# 1. PushSimulator.execute validates the pushes up front, naming the argument


def test_execute_nan_push_start_names_the_argument(sim, scene):
    scene.push_origin[0] = np.nan  # arrays are mutable: caught again at execute
    with pytest.raises(
        InputError,
        match=r"scenes\[0\]\.push_origin \(the push start\) "
        r"contains 1 NaN",
    ):
        sim.execute([scene])


def test_execute_rejects_empty_and_foreign_scenes(sim, scene):
    with pytest.raises(InputError, match="scenes must be a non-empty list of SceneInstance"):
        sim.execute([])
    with pytest.raises(InputError, match=r"scenes\[1\] must be a SceneInstance"):
        sim.execute([scene, {"push_origin": [0, 0]}])


def test_nan_push_start_rejected_on_construction(scene):
    with pytest.raises(InputError, match=r"SceneInstance\.push_origin contains 1 NaN"):
        dataclasses.replace(scene, push_origin=np.array([np.nan, 0.0]))
    with pytest.raises(InputError, match=r"SceneInstance\.push_yaw contains 1 NaN"):
        dataclasses.replace(scene, push_yaw=math.inf)


# 2. run() checks its count at the call, not when the first sample is asked for


@pytest.mark.parametrize("n", [2.5, -3, "3", True, math.nan])
def test_run_count_is_checked_at_the_call(sim, n):
    with pytest.raises(InputError, match=r"n must be an integer >= 0, got "):
        sim.run(n, np.random.default_rng(0))  # no list(): raising here, not lazily


def test_run_rejects_a_non_generator_rng(sim):
    with pytest.raises(InputError, match=r"rng must be a numpy\.random\.Generator"):
        sim.run(1, 0)


def test_run_zero_is_empty(sim):
    assert list(sim.run(0, np.random.default_rng(0))) == []


# 3. physical parameters are validated before anything reaches pymunk


@pytest.mark.parametrize(
    ("field", "value", "message"),
    [
        ("mass", [-0.5], r"SceneInstance\.mass\[0\] must be a finite number > 0, got -0\.5"),
        ("mass", [0.0], r"SceneInstance\.mass\[0\] must be a finite number > 0"),
        (
            "ground_friction",
            [-0.3],
            r"SceneInstance\.ground_friction\[0\] must be a finite number >= 0, got -0\.3",
        ),
        (
            "contact_friction",
            [-1.0],
            r"SceneInstance\.contact_friction\[0\] must be a finite number >= 0, got -1\.0",
        ),
        ("poses", [[0.0, np.nan, 0.0]], r"SceneInstance\.poses contains 1 NaN"),
        ("poses", [[0.0, 0.0]], r"SceneInstance\.poses has shape \(1, 2\), expected \(1, 3\)"),
        ("mass", [1.0, 1.0], r"SceneInstance\.mass has shape \(2,\), expected \(1\)"),
        ("walls", [[0.0, 0.0, math.inf, 1.0]], r"SceneInstance\.walls contains 1 NaN"),
        ("push_distance", -0.1, r"SceneInstance\.push_distance must be a finite number > 0"),
        (
            "support_weights",
            (np.array([-1.0]),),
            r"SceneInstance\.support_weights\[0\] must be a non-empty array of loads >= 0",
        ),
        ("support_weights", (), r"support_weights has 0 entries for 1 objects"),
        ("objects", (), r"SceneInstance\.objects must be a non-empty tuple of ObjectSpec"),
    ],
)
def test_scene_instance_rejects_bad_physics(scene, no_pymunk, field, value, message):
    with pytest.raises(InputError, match=message):
        dataclasses.replace(scene, **{field: value})


@pytest.mark.parametrize(
    ("field", "value"), [("mass", -1.0), ("ground_friction", -0.2), ("contact_friction", -0.4)]
)
def test_simulate_push_revalidates_before_pymunk(world, scene, no_pymunk, field, value):
    """A scene changed in place after construction still never reaches Chipmunk."""
    getattr(scene, field)[0] = value
    path = straight_path(world, scene.push_origin, scene.push_yaw, scene.push_distance)
    with pytest.raises(InputError, match=rf"SceneInstance\.{field}\[0\] must be a finite number"):
        simulate_push(world, scene, path)


def test_nominal_from_a_bad_catalogue_entry_is_rejected(world):
    book = load_catalogue()["book"]
    with pytest.raises(ConfigError, match=r"ObjectSpec\.mass must be a finite number > 0"):
        dataclasses.replace(book, mass=-1.0)
    with pytest.raises(ConfigError, match=r"ObjectSpec\.size\[1\] must be a finite number > 0"):
        dataclasses.replace(book, size=(0.1, 0.0))
    with pytest.raises(ConfigError, match=r"ObjectSpec\.ground_friction must be a finite"):
        dataclasses.replace(book, ground_friction=-0.1)
    with pytest.raises(ConfigError, match=r"ObjectSpec\.shape of 'book' must be 'box' or"):
        dataclasses.replace(book, shape="cone")


def test_world_specs_reject_bad_physics(world):
    with pytest.raises(ConfigError, match=r"GripperSpec\.mass must be a finite number > 0"):
        dataclasses.replace(world.gripper, mass=-1.0)
    with pytest.raises(ConfigError, match=r"GripperSpec\.contact_friction must be a finite"):
        dataclasses.replace(world.gripper, contact_friction=-1.0)
    with pytest.raises(ConfigError, match=r"PhysicsSpec\.substeps must be a positive integer"):
        dataclasses.replace(world.physics, substeps=0)
    with pytest.raises(ConfigError, match=r"TabletopSpec\.push_speed must be a finite number"):
        dataclasses.replace(world, push_speed=math.nan)
    with pytest.raises(ConfigError, match=r"WarehouseSpec\.box_mass must be a finite number"):
        dataclasses.replace(load_warehouse(), box_mass=-2.0)


def test_pymunk_door_checks_leave_the_space_untouched():
    space = pymunk.Space()
    support, weights = np.zeros((1, 2)), np.ones(1)
    with pytest.raises(InputError, match="mass must be a finite number > 0"):
        add_sliding_body(space, -1.0, pymunk.Circle, (0, 0, 0), support, weights, 0.5, 9.81)
    with pytest.raises(InputError, match="mu must be a finite number >= 0"):
        add_sliding_body(space, 1.0, pymunk.Circle, (0, 0, 0), support, weights, -0.5, 9.81)
    with pytest.raises(InputError, match="2 support weights for 1 support points"):
        add_sliding_body(space, 1.0, pymunk.Circle, (0, 0, 0), support, np.ones(2), 0.5, 9.81)
    with pytest.raises(InputError, match="mass must be a finite number > 0"):
        TrackedPusher(space, np.zeros(3), -1.0, 1.0, lambda b: [], 1.0, 1.0, 1.0)
    with pytest.raises(InputError, match="pose contains 1 NaN"):
        TrackedPusher(space, np.array([0.0, np.nan, 0.0]), 1.0, 1.0, lambda b: [], 1.0, 1.0, 1.0)
    assert not space.bodies and not space.shapes and not space.constraints


# 4. NaN in the hand path or the object poses is refused, not turned into an outcome


def test_nan_hand_path_is_refused(world, scene, no_pymunk):
    path = straight_path(world, scene.push_origin, scene.push_yaw, scene.push_distance)
    path[5, 0] = np.nan
    with pytest.raises(InputError, match="hand_path contains 1 NaN"):
        simulate_push(world, scene, path)
    with pytest.raises(InputError, match=r"hand_path has shape \(4, 2\), expected \(\*, 3\)"):
        simulate_push(world, scene, np.zeros((4, 2)))
    with pytest.raises(InputError, match="hand_path is empty"):
        simulate_push(world, scene, np.zeros((0, 3)))


def test_nan_object_pose_is_refused(world, scene, no_pymunk):
    scene.poses[0, 2] = np.nan
    path = straight_path(world, scene.push_origin, scene.push_yaw, scene.push_distance)
    with pytest.raises(InputError, match=r"SceneInstance\.poses contains 1 NaN"):
        simulate_push(world, scene, path)


def test_effect_of_nan_poses_is_refused():
    ok = np.zeros((1, 3))
    with pytest.raises(InputError, match="after contains 1 NaN"):
        push_frame_effect(ok, np.array([[np.nan, 0.0, 0.0]]), 0.0)
    with pytest.raises(InputError, match="push_yaw contains 1 NaN"):
        push_frame_effect(ok, ok, math.nan)
    with pytest.raises(InputError, match=r"after has shape \(2, 3\), expected \(1, 3\)"):
        push_frame_effect(ok, np.zeros((2, 3)), 0.0)


# 7. sim's offset array no longer shares probaff.maps.DIRECTIONS' name


def test_the_offsets_live_only_under_their_own_name():
    assert "DIRECTIONS" not in warehouse_module.__all__
    assert not hasattr(warehouse_module, "DIRECTIONS")


def test_push_box_direction_must_be_an_index():
    spec = load_warehouse()
    m = warehouse_module.WarehouseMap.from_boxes((3, 3), [(1, 1)])
    with pytest.raises(InputError, match=r"direction must be 0\.\.3 .*got 1\.5"):
        warehouse_module.push_box(spec, m, (1, 1), 1.5)
    with pytest.raises(InputError, match="cell_size must be a finite number > 0"):
        warehouse_module.WarehouseMap(m.occupancy, cell_size=-1.0)


# 8. scene builders refuse overlapping or off-table objects and inputs of the wrong type


def test_tabletop_objects_that_overlap_are_refused(world, no_pymunk):
    book = load_catalogue()["book"]
    grid = world.physics.friction_grid
    with pytest.raises(
        InputError, match=r"objects 0 \(book\) and 1 \(book\) overlap by \d+\.\d mm at the start"
    ):
        SceneInstance.nominal(
            [book, book], [[0.0, 0.0, 0.0], [0.05, 0.0, 0.3]], [-0.13, 0.0], 0.0, 0.15, grid
        )
    # footprints in contact are accepted, and so is what the physics leaves after a push: a
    # book pushed against another rests a few millimetres into it (2.4 mm seen in a planning
    # episode, whose next push starts from there)
    touching = [[0.0, 0.0, 0.0], [book.size[0] + 0.001, 0.0, 0.0]]
    SceneInstance.nominal([book, book], touching, [-0.13, 0.0], 0.0, 0.15, grid)
    pressed = [[0.0, 0.0, 0.0], [book.size[0] - 0.004, 0.0, 0.0]]
    SceneInstance.nominal([book, book], pressed, [-0.13, 0.0], 0.0, 0.15, grid)
    with pytest.raises(InputError, match=r"overlap by 12\.0 mm"):
        deep = [[0.0, 0.0, 0.0], [book.size[0] - 0.012, 0.0, 0.0]]
        SceneInstance.nominal([book, book], deep, [-0.13, 0.0], 0.0, 0.15, grid)


def test_tabletop_objects_off_the_table_are_refused(world, scene, sim, no_pymunk):
    path = straight_path(world, scene.push_origin, scene.push_yaw, scene.push_distance)
    off = dataclasses.replace(scene, poses=np.array([[0.8, 0.0, 0.0]]))
    with pytest.raises(InputError, match=r"poses\[0\] puts 'book'.s centre at \(0\.800, 0\.000\)"):
        simulate_push(world, off, path)
    with pytest.raises(InputError, match=r"scenes\[0\]: SceneInstance\.poses\[0\] .* off the 1 x"):
        sim.execute([off])


def test_push_entry_points_refuse_wrong_types(world, scene, no_pymunk):
    path = straight_path(world, scene.push_origin, scene.push_yaw, scene.push_distance)
    with pytest.raises(InputError, match="world must be a TabletopSpec"):
        simulate_push("tabletop", scene, path)
    with pytest.raises(InputError, match="scene must be a SceneInstance"):
        simulate_push(world, {"poses": [0, 0, 0]}, path)
    with pytest.raises(InputError, match=r"hand_path must be a \(T_c, 3\) numeric array"):
        simulate_push(world, scene, [["a", 0, 0]])
    with pytest.raises(InputError, match="scene must be a scene name"):
        PushSimulator(3)
    with pytest.raises(InputError, match=r"distance must be a finite number > 0, got '0\.15'"):
        straight_path(world, [0.0, 0.0], 0.0, "0.15")
    with pytest.raises(InputError, match=r"start_xy has shape \(3,\), expected \(2\)"):
        straight_path(world, [0.0, 0.0, 0.0], 0.0, 0.15)
    with pytest.raises(InputError, match="distance must be a finite number > 0, got 0"):
        trapezoid_progress(0, 0.2, 1.0, 40.0)


def test_spec_fields_must_be_numbers():
    book = load_catalogue()["book"]
    with pytest.raises(ConfigError, match=r"ObjectSpec\.mass must be a number, got '1'"):
        dataclasses.replace(book, mass="1")
    with pytest.raises(ConfigError, match=r"ObjectSpec\.size\[0\] must be a number, got True"):
        dataclasses.replace(book, size=(True, 0.1))


def test_warehouse_builders_name_bad_cells_and_types():
    spec = load_warehouse()
    WarehouseMap = warehouse_module.WarehouseMap
    with pytest.raises(InputError, match=r"boxes\[0\]\[0\] must be an integer, got 0\.5"):
        WarehouseMap.from_boxes((4, 4), [(0.5, 1)])
    with pytest.raises(InputError, match=r"boxes\[0\] must be a \(row, col\) pair of integers"):
        WarehouseMap.from_boxes((4, 4), [1, 2])
    with pytest.raises(InputError, match=r"shape\[1\] must be an integer >= 2, got 1"):
        WarehouseMap.from_boxes((4, 1), [])
    with pytest.raises(InputError, match="cell_size must be a finite number > 0, got '1'"):
        WarehouseMap(np.zeros((3, 3), dtype=bool), "1")
    m = WarehouseMap.from_boxes((3, 3), [(1, 1)])
    with pytest.raises(InputError, match=r"cell\[0\] must be an integer, got 1\.5"):
        warehouse_module.push_box(spec, m, (1.5, 1), 0)
    with pytest.raises(InputError, match="spec must be a WarehouseSpec"):
        warehouse_module.push_box("warehouse.yaml", m, (1, 1), 0)
    with pytest.raises(InputError, match="m must be a WarehouseMap"):
        warehouse_module.physics_affordances(spec, m.occupancy)
    with pytest.raises(InputError, match=r"direction must be 0\.\.3 .*got 7"):
        m.moved((1, 1), 7)
    with pytest.raises(InputError, match=r"rng must be a numpy\.random\.Generator"):
        warehouse_module.generate_map(spec, 3)
    with pytest.raises(InputError, match="m must be a WarehouseMap"):
        DepthSensor(spec, "map")
    with pytest.raises(InputError, match=r"rng must be a numpy\.random\.Generator"):
        DepthSensor(spec, m).scan([0.5, 0.5], 0)


def test_warehouse_camera_must_see_the_floor():
    spec = load_warehouse()
    assert spec.sensor_kind == "camera"
    with pytest.raises(
        ConfigError,
        match=r"WarehouseSpec\.sensor_height 10 m leaves the camera .* must lie in \[0\.000, 2\.4",
    ):
        dataclasses.replace(spec, sensor_height=10.0)
    with pytest.raises(ConfigError, match=r"camera_tilt_deg -40 points the camera wholly above"):
        dataclasses.replace(spec, camera_tilt_deg=-40.0)
    with pytest.raises(ConfigError, match=r"camera_tilt_deg must be a number of degrees, got '10'"):
        dataclasses.replace(spec, camera_tilt_deg="10")
    with pytest.raises(ConfigError, match=r"sensor_elevations must be a non-empty tuple of angles"):
        dataclasses.replace(spec, sensor_elevations=(0.0, math.nan))


def test_point_clouds_refuse_bad_objects_poses_and_streams():
    book = load_catalogue()["book"]
    rng = np.random.default_rng(0)
    with pytest.raises(InputError, match="pose contains 1 NaN"):
        object_cloud(book, [0.0, np.nan, 0.0], 10, 0.0, rng)
    with pytest.raises(InputError, match="obj must be a catalogue ObjectSpec"):
        object_cloud("book", [0.0, 0.0, 0.0], 10, 0.0, rng)
    with pytest.raises(InputError, match=r"rng must be a numpy\.random\.Generator"):
        object_cloud(book, [0.0, 0.0, 0.0], 10, 0.0, 0)
    with pytest.raises(InputError, match="objects must be a non-empty list"):
        scan_scene((), np.zeros((0, 3)), (1.0, 0.8), rng)
    with pytest.raises(InputError, match=r"poses has shape \(1, 2\), expected \(1, 3\)"):
        scan_scene((book,), [[0.0, 0.0]], (1.0, 0.8), rng)
    with pytest.raises(InputError, match=r"table_size\[1\] must be a finite number > 0"):
        table_cloud((1.0, -0.8), 0.02, 0.0, rng)
    with pytest.raises(InputError, match="table_size must hold numbers"):
        table_cloud(("a", 0.8), 0.02, 0.0, rng)


def test_side_view_and_camera_entry_points_refuse_strings():
    side = load_sideview()
    cube = SideViewScene.nominal("pick", ["cube_10"], np.array([[0.0, 0.05, 0.0]]), 0)
    with pytest.raises(InputError, match=r"duration must be a finite number > 0 \(s\), got '1'"):
        simulate_rest(side, cube, "1")
    with pytest.raises(InputError, match="world must be a SideViewSpec"):
        simulate_rest("sideview.yaml", cube, 1.0)
    with pytest.raises(InputError, match="initial_opening must hold numbers"):
        simulate_sideview(side, cube, np.zeros((2, 3)), np.zeros(2), initial_opening="open")
    with pytest.raises(InputError, match=r"world must be a SideViewSpec \(load_sideview\(\)\)"):
        plan_skills([cube], world="sideview.yaml")
    with pytest.raises(InputError, match=r"boxes must be an \(N, 7\) array of numbers"):
        PrimitiveScene(boxes=[["a"] * 7])
    with pytest.raises(InputError, match="pans_deg must hold numbers"):
        head_views(np.eye(4), "left", [30.0])
    with pytest.raises(InputError, match="poses must hold numbers"):
        scan_views(DepthCamera(), PrimitiveScene([[0, 0, 0, 1, 1, 1, 0]], [0]), "front")


def test_the_shared_checks_name_the_argument():
    from probaff.sim.inputs import (
        check_items,
        check_objects,
        check_rng,
        check_type,
        float_rows,
        floats,
    )

    with pytest.raises(InputError, match=r"x must hold numbers, got 'a'"):
        floats("x", "a")
    assert float_rows("b", np.zeros(0), 7).shape == (0, 7)
    with pytest.raises(InputError, match=r"b has shape \(2, 6\), expected \(\*, 7\)"):
        float_rows("b", np.zeros((2, 6)), 7)
    with pytest.raises(InputError, match="b contains 7 NaN or infinite"):
        float_rows("b", np.array([[np.nan] * 7]), 7)
    with pytest.raises(InputError, match=r"w must be a int \(an int\), got str"):
        check_type("w", "3", int, "an int")
    with pytest.raises(InputError, match=r"rng must be a numpy\.random\.Generator"):
        check_rng(0)
    with pytest.raises(InputError, match="wrap a single scene in a list"):
        check_items("scenes", [], int, "")
    with pytest.raises(InputError, match=r"scenes\[1\] must be a int"):
        check_items("scenes", [1, "2"], int, "")
    with pytest.raises(InputError, match=r"S\.objects must be a non-empty tuple of ObjectSpec"):
        check_objects("S", [], "load_catalogue()")
