"""Bad input to the simulator ends in a ProbaffError naming the argument, before pymunk sees it.

pymunk wraps Chipmunk, a C library: a negative mass or friction aborts the whole Python process
there, so these tests check that validation raises first (pymunk is replaced by a tripwire
where a bad value would reach it).
"""

import dataclasses
import math

import numpy as np
import pymunk
import pytest

from probaff.errors import ConfigError, InputError
from probaff.grid import DIRECTION_OFFSETS
from probaff.sim import (
    PushSimulator,
    SceneInstance,
    load_catalogue,
    load_tabletop,
    push_frame_effect,
    simulate_push,
    straight_path,
)
from probaff.sim import tabletop as tabletop_module
from probaff.sim import warehouse as warehouse_module
from probaff.sim.config import load_warehouse
from probaff.sim.friction import add_sliding_body
from probaff.sim.pusher import TrackedPusher


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


def test_directions_alias_is_deprecated():
    assert "DIRECTIONS" not in warehouse_module.__all__
    with pytest.warns(DeprecationWarning, match="use probaff.grid.DIRECTION_OFFSETS"):
        alias = warehouse_module.DIRECTIONS
    assert alias is DIRECTION_OFFSETS
    with pytest.raises(AttributeError):
        warehouse_module.NO_SUCH_NAME  # noqa: B018


def test_push_box_direction_must_be_an_index():
    spec = load_warehouse()
    m = warehouse_module.WarehouseMap.from_boxes((3, 3), [(1, 1)])
    with pytest.raises(InputError, match=r"direction must be 0\.\.3 .*got 1\.5"):
        warehouse_module.push_box(spec, m, (1, 1), 1.5)
    with pytest.raises(InputError, match="cell_size must be a finite number > 0"):
        warehouse_module.WarehouseMap(m.occupancy, cell_size=-1.0)
