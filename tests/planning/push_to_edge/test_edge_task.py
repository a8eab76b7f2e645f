"""The push-to-edge task: goal geometry, falls, collisions, candidates and episode starts."""

import math

import numpy as np
import pytest

from probaff.errors import ConfigError, InputError
from probaff.planning.geometry import box_corners
from probaff.planning.push_to_edge.task import (
    START_OVERLAP,
    EdgeTask,
    load_edge_task,
    sample_episode,
)


def test_grasp_geometry_comes_from_the_gripper(task):
    r = task.world.gripper.finger_radius
    assert task.grasp_depth == pytest.approx(2 * r + task.clearance)
    assert task.finger_width == pytest.approx(2 * r)
    assert task.half_diagonal == pytest.approx(0.5 * math.hypot(*task.book.size))


def test_graspable_needs_overhang_and_the_centre_on_the_table(task):
    e, d = task.edge_x, task.grasp_depth
    a = 0.5 * task.book.size[0]
    ok = np.array([e + d + 0.01 - a, 0.0, 0.0])  # overhangs d + 1 cm, centre inside
    short = np.array([e + d - 0.01 - a, 0.0, 0.0])  # overhangs 1 cm less than d
    tipping = np.array([e - task.com_margin / 2, 0.0, 0.0])
    assert task.graspable(np.stack([ok, short, tipping])).tolist() == [True, False, False]
    # a corner that pokes out by d but is narrower than a fingertip there is not enough
    corner = np.array([e + d + 0.004 - task.half_diagonal, 0.0, math.atan2(0.17, 0.24)])
    assert not task.graspable(corner)


def test_fallen_is_the_simulators_rule(task):
    hx, hy = 0.5 * task.world.table_size[0], 0.5 * task.world.table_size[1]
    poses = np.array([[hx - 1e-3, 0, 0], [hx + 1e-3, 0, 0], [0, -hy - 1e-3, 0]])
    assert task.fallen(poses).tolist() == [False, True, True]


def test_heuristic_is_a_lower_bound_on_the_moves_needed(task):
    rng = np.random.default_rng(0)
    poses = np.column_stack(
        [rng.uniform(-0.3, 0.45, 500), rng.uniform(-0.3, 0.3, 500), rng.uniform(-3, 3, 500)]
    )
    h = task.heuristic(poses)
    goals = poses[task.graspable(poses)]
    assert (task.heuristic(goals) == 0).all()
    # the goal set lies at x >= edge + d_g - R, and a push moves the centre <= step_bound
    needed = np.maximum(task.edge_x + task.grasp_depth - task.half_diagonal - poses[:, 0], 0)
    assert (h * task.search.step_bound >= needed - 1e-9).all()
    assert (h <= np.ceil(needed / task.search.step_bound) + 1e-9).all()


def test_candidates_start_behind_the_book_and_point_at_its_centre(task):
    pose = np.array([[0.1, -0.05, 0.4]])
    origins, yaws = task.candidate_pushes(pose)
    assert origins.shape == (1, task.directions, 2) and yaws.shape == (task.directions,)
    to_centre = pose[0, :2] - origins[0]
    ang = np.arctan2(to_centre[:, 1], to_centre[:, 0])
    assert np.allclose(np.angle(np.exp(1j * (ang - yaws))), 0, atol=1e-9)
    # the fingertip starts start_gap + r_f from the footprint, never inside it
    corners = box_corners(pose[0], task.book.size)
    d = np.stack([np.cos(yaws), np.sin(yaws)], -1)
    behind = ((corners[None] - origins[0][:, None]) * d[:, None]).sum(-1).min(1)
    assert np.allclose(behind, task.start_gap + task.world.gripper.finger_radius)


def test_episodes_are_seeded_and_start_apart(task):
    a = sample_episode(task, np.random.default_rng(5))
    b = sample_episode(task, np.random.default_rng(5))
    assert np.array_equal(a.poses, b.poses) and np.array_equal(a.mass, b.mass)
    for seed in range(20):
        s = sample_episode(task, np.random.default_rng(seed))
        assert task.start_x[0] <= s.poses[0, 0] <= task.start_x[1]
        assert not task.collides(s.poses[0], s.poses[1])
        assert not task.graspable(s.poses[0])
        assert [o.name for o in s.objects] == ["book", "battery"]


def test_a_goal_unreachable_by_construction_is_refused(task):
    with pytest.raises(ConfigError, match="unreachable by construction"):
        EdgeTask(task.scene, task.world, clearance=0.5)
    with pytest.raises(ConfigError, match="reaches the goal already"):
        EdgeTask(task.scene, task.world, start_x=(-0.1, 0.45))


@pytest.mark.parametrize(
    ("kw", "match"),
    [
        ({"budget": 0}, "budget .* must be a positive integer, got 0"),
        ({"budget": -3}, "budget .* must be a positive integer, got -3"),
        ({"directions": 2.5}, "directions must be a positive integer"),
        ({"replan_distance": float("nan")}, "replan_distance must be a finite number"),
    ],
)
def test_bad_task_settings(task, kw, match):
    with pytest.raises(InputError, match=match):
        EdgeTask(task.scene, task.world, **kw)


def test_task_file_errors_name_the_key(tmp_path):
    bad = tmp_path / "t.yaml"
    bad.write_text("scene: push_to_edge\nbudgett: 3\n")
    with pytest.raises(ConfigError, match="unknown field\\(s\\) \\['budgett'\\]"):
        load_edge_task(bad)
    bad.write_text("scene: push_to_edge\nbudget: 0\n")
    with pytest.raises(ConfigError, match="budget"):
        load_edge_task(bad)
    with pytest.raises(ConfigError, match="no task file"):
        load_edge_task(tmp_path / "missing.yaml")
    bad.write_text("scene: push_to_edge\nsearch: [1, 2]\n")
    with pytest.raises(ConfigError, match=r"t\.yaml:search must be a mapping, got list"):
        load_edge_task(bad)
    bad.write_text("risk:\n  samples: 4\n  max_falls: 0.2\n")
    with pytest.raises(ConfigError, match=r"t.yaml:risk has unknown field\(s\) \['max_falls'\]"):
        load_edge_task(bad)


def test_a_fallen_book_is_never_graspable(task):
    # overhangs the edge by enough, centre inside it: a goal on the table, not off its +y side
    on_table = np.array([0.42, 0.0, 0.0])
    off_side = np.array([0.42, 0.50, 0.0])
    assert task.graspable(np.stack([on_table, off_side])).tolist() == [True, False]


def test_a_start_off_the_table_or_on_the_battery_is_refused(task):
    with pytest.raises(InputError, match=r"start pose of the book, \[0.42, 0.5, 0.0\], is off the"):
        task.check_start(np.array([0.42, 0.50, 0.0]), np.array([-0.4, 0.35, 0.0]))
    with pytest.raises(InputError, match=r"start pose of the battery, \[0.0, -0.6, 0.0\], is off"):
        task.check_start(np.zeros(3), np.array([0.0, -0.6, 0.0]))
    with pytest.raises(InputError, match=r"start pose of the book, .* overlaps the battery"):
        task.check_start(np.zeros(3), np.array([0.05, 0.0, 0.0]))


def test_a_replan_from_a_book_pressed_into_the_battery_is_accepted(task):
    """A push leaves the book a few millimetres into the battery it was pushed against."""
    gap = 0.5 * (task.book.size[0] + task.battery.size[0])
    pressed = np.array([gap - 0.006, 0.0, 0.0])
    assert bool(task.collides(np.zeros(3), pressed))  # a collision for the planner's model
    _, battery = task.check_start(np.zeros(3), pressed)  # but a valid start
    assert np.array_equal(battery, pressed)
    with pytest.raises(InputError, match="overlaps the battery"):
        task.check_start(np.zeros(3), np.array([gap - START_OVERLAP - 0.001, 0.0, 0.0]))


@pytest.mark.parametrize(
    ("kw", "match"),
    [
        ({"start_y": (0.45, 0.5)}, r"start.y = \[0.45, 0.5\] leaves the table"),
        ({"start_x": (-float("inf"), 0.0)}, r"start.x = \[-inf, 0.0\] leaves the table"),
        ({"start_gap": 0.2}, "start_gap = 0.2 m is not shorter than the push distance"),
        ({"scene": "push_to_edge"}, "scene must be a SceneSpec"),
        ({"world": None}, "world must be a TabletopSpec"),
    ],
)
def test_bad_task_geometry_is_refused(task, kw, match):
    args = {"scene": task.scene, "world": task.world, **kw}
    with pytest.raises(ConfigError, match=match):
        EdgeTask(**args)


def test_sample_episode_needs_a_task_and_a_generator(task):
    with pytest.raises(InputError, match=r"rng must be a numpy.random.Generator"):
        sample_episode(task, 0)  # type: ignore[arg-type]
    with pytest.raises(InputError, match="task must be an EdgeTask"):
        sample_episode("push_to_edge", np.random.default_rng(0))  # type: ignore[arg-type]


def test_a_task_file_that_is_not_yaml_is_a_config_error(tmp_path):
    binary = tmp_path / "task.yaml"
    binary.write_bytes(b"\xff\xfe\x00binary")
    with pytest.raises(ConfigError, match="is not UTF-8 text"):
        load_edge_task(binary)
    broken = tmp_path / "broken.yaml"
    broken.write_text("scene: [unclosed\n")
    with pytest.raises(ConfigError, match="is not valid YAML"):
        load_edge_task(broken)
