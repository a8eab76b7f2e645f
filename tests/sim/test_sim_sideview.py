"""The side-view pick-and-place world: loading, physics, the pick and place skills."""

import dataclasses
import math
import re
import shutil

import numpy as np
import pytest

from probaff.errors import ConfigError, InputError, UnreachablePoseError
from probaff.sim import (
    SideViewScene,
    load_catalogue,
    load_sideview,
    load_sideview_scene,
    run_skills,
)
from probaff.sim.sideview import simulate_rest
from probaff.sim.sideview_config import list_sideview_scenes
from probaff.sim.skills import pick, place, plan_skills, sample_sideview_scenes, simulate_skill
from probaff.sim.world_files import worlds_dir


@pytest.fixture(scope="module")
def world():
    return load_sideview()


@pytest.fixture(scope="module")
def cat(world):
    return load_catalogue(world.catalogue)


def _on_table(name, x, cat):
    return [x, 0.5 * cat[name].height, 0.0]


def _pick_scene(names, poses, target=None):
    return SideViewScene.nominal(
        "pick", names, np.array(poses), len(names) - 1 if target is None else target
    )


def _place_scene(world, cat, support, x, release, offset=0.0):
    """A held cube_10 above the table (support None) or above a support object at x."""
    h = cat["cube_10"].height
    if support is None:
        top = 0.0
        names, poses = [], []
    else:
        names, poses = [support], [_on_table(support, x, cat)]
        top = cat[support].height
    names.append("cube_10")
    poses.append([x + offset, top + world.place.hold_height + 0.5 * h, 0.0])
    return SideViewScene.nominal(
        "place", names, np.array(poses), len(names) - 1, -1 if support is None else 0, release
    )


def test_world_and_catalogue_load(world, cat):
    assert world.gripper.span == pytest.approx(0.15)
    for name in ["cube_10", "cube_15", "cube_20", "block_25x10", "tall_12x20", "flat_20x12"]:
        assert name in cat and cat[name].shape == "box"
    assert cat["tall_12x20"].height > cat["tall_12x20"].size[0]
    assert cat["flat_20x12"].height < cat["flat_20x12"].size[0]
    assert any(o.size[0] > world.gripper.span for o in cat.values())
    assert {"pick", "place"} <= set(list_sideview_scenes())
    spec = load_sideview_scene("place")
    assert spec.skill == "place" and spec.held is not None and spec.held.name == "cube_10"


def test_world_file_errors_name_the_key(tmp_path, monkeypatch):
    for f in ["tabletop.yaml", "arm.urdf", "cuboids.yaml", "sideview.yaml"]:
        shutil.copy(worlds_dir() / f, tmp_path / f)
    text = (tmp_path / "sideview.yaml").read_text()
    (tmp_path / "sideview.yaml").write_text(text.replace("squeeze_force:", "squeeze_farce:"))
    with pytest.raises(ConfigError, match="squeeze_force"):
        load_sideview(tmp_path / "sideview.yaml")
    (tmp_path / "sideview.yaml").write_text(re.sub(r"substeps: \d+", "substeps: 0.5", text))
    with pytest.raises(ConfigError, match="substeps"):
        load_sideview(tmp_path / "sideview.yaml")
    (tmp_path / "sideview.yaml").write_text(text)
    monkeypatch.setenv("PROBAFF_WORLDS", str(tmp_path))
    (tmp_path / "sideview_scenes").mkdir()
    (tmp_path / "sideview_scenes" / "bad.yaml").write_text(
        "skill: pick\nobjects:\n  - choices: [cube_11]\n    x: [0, 0.1]\n"
    )
    with pytest.raises(ConfigError, match="cube_11"):
        load_sideview_scene("bad")


def test_cube_settles_on_the_table_and_stays(world, cat):
    scene = _pick_scene(["cube_10"], [_on_table("cube_10", 0.05, cat)])
    _, objs = simulate_rest(world, scene, 1.0)
    z = objs[:, 0, 1]
    assert z[-1] == pytest.approx(0.05, abs=1e-3)
    half = len(z) // 2
    assert np.ptp(objs[half:, 0, 0]) < 1e-4 and np.ptp(z[half:]) < 1e-4
    assert abs(objs[-1, 0, 2]) < 1e-3


def test_stack_of_two_settles(world, cat):
    scene = _pick_scene(
        ["cube_15", "cube_10"],
        [_on_table("cube_15", 0.0, cat), [0.02, 0.15 + 0.05, 0.0]],
    )
    _, objs = simulate_rest(world, scene, 1.0)
    assert objs[-1, 0, 1] == pytest.approx(0.075, abs=1e-3)
    assert objs[-1, 1, 1] == pytest.approx(0.20, abs=2e-3)
    assert np.abs(objs[-1, :, 0] - [0.0, 0.02]).max() < 1e-3
    assert np.abs(objs[-1, :, 2]).max() < 2e-3


def _squeezed(world, force):
    return dataclasses.replace(
        world, gripper=dataclasses.replace(world.gripper, squeeze_force=force)
    )


def _min_squeeze(world, cat, name):
    """The friction analysis' least squeeze force (N) that holds `name` against gravity."""
    mu = math.sqrt(world.gripper.pad_friction * cat[name].contact_friction)
    return cat[name].mass * world.physics.gravity / (2 * mu)


def test_min_squeeze_force_matches_friction_analysis(world, cat):
    scene = _pick_scene(["cube_10"], [_on_table("cube_10", 0.0, cat)])
    plan = plan_skills([scene], world)[0]
    analytic = _min_squeeze(world, cat, "cube_10")

    def lifts(force):
        out = simulate_skill(scene, plan, _squeezed(world, force))
        return out.lifted and not out.slipped

    lo, hi = 0.5 * analytic, 1.5 * analytic
    assert lifts(hi) and not lifts(lo)
    for _ in range(5):
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if lifts(mid) else (mid, hi)
    assert 0.5 * (lo + hi) == pytest.approx(analytic, rel=0.10)


def test_slip_is_reported_when_the_fingers_reach_a_narrow_post_late(world, cat):
    """Closing ends before the fingers reach the 5 cm post; the lift's slip still counts."""
    scene = _pick_scene(["post_5x15"], [_on_table("post_5x15", 0.0, cat)])
    plan = plan_skills([scene], world)[0]
    weak = simulate_skill(
        scene, plan, _squeezed(world, 1.05 * _min_squeeze(world, cat, "post_5x15"))
    )
    assert weak.slipped or not weak.lifted
    assert weak.slipped  # it rises but slides several cm down between the fingers
    rise = weak.state_after[0, 1] - weak.state_before[0, 1]
    assert rise < world.pick.lift - 2 * world.slip_tolerance
    nominal = simulate_skill(scene, plan, world)
    assert nominal.lifted and not nominal.slipped


def test_pick_lifts_a_graspable_object(world, cat):
    out = pick(_pick_scene(["cube_10"], [_on_table("cube_10", 0.05, cat)]), world)
    assert out.skill == "pick" and out.grasped and out.lifted and not out.slipped
    assert not out.placed
    rise = out.state_after[0, 1] - out.state_before[0, 1]
    assert rise == pytest.approx(world.pick.lift, abs=0.02)
    assert abs(out.state_after[0, 0] - 0.05) < 0.01
    T, K = len(out.times), len(out.object_specs)
    assert out.ee_commanded.shape == out.ee_actual.shape == (T, 3)
    assert out.opening_commanded.shape == out.opening_actual.shape == (T,)
    assert out.objects.shape == (T, K, 3)
    assert out.state_before.shape == out.state_after.shape == (K, 3)
    assert out.q_waypoints.ndim == 2 and out.q_waypoints.shape[1] == 6
    assert np.all(np.diff(out.times) > 0)
    # the fingers end closed on the 10 cm cube, the hand tracks its command within a few mm
    assert out.opening_actual[-1] == pytest.approx(cat["cube_10"].size[0], abs=3e-3)
    assert np.abs(out.ee_actual[:, :2] - out.ee_commanded[:, :2]).max() < 0.01
    # commanded tcp: from 15 cm above the top, down to half the height, up by the lift
    assert out.ee_commanded[0, 1] == pytest.approx(0.10 + 0.15, abs=2e-3)
    assert out.ee_commanded[:, 1].min() == pytest.approx(0.05, abs=2e-3)


def test_pick_from_a_stack_and_failures(world, cat):
    stacked = _pick_scene(
        ["cube_15", "cube_10"], [_on_table("cube_15", -0.05, cat), [-0.05, 0.20, 0.0]]
    )
    wide = _pick_scene(["block_25x10"], [_on_table("block_25x10", 0.0, cat)])
    heavy = _pick_scene(["heavy_12"], [_on_table("heavy_12", 0.1, cat)])
    top, too_wide, too_heavy = run_skills([stacked, wide, heavy], world)
    assert top.grasped and top.lifted
    assert np.abs(top.state_after[0, :2] - top.state_before[0, :2]).max() < 0.01  # bottom stays
    assert not too_wide.grasped and not too_wide.lifted
    assert np.abs(too_wide.state_after[0] - too_wide.state_before[0]).max() < 0.01
    assert too_heavy.slipped and not too_heavy.lifted


@pytest.mark.parametrize("support", [None, "cube_15"])
def test_place_puts_the_cube_on_its_target(world, cat, support):
    scene = _place_scene(world, cat, support, 0.05, release=0.06, offset=0.01)
    out = place(scene, world)
    top = 0.0 if support is None else cat[support].height
    assert out.grasped and out.placed and not out.slipped
    assert out.state_after[-1, 1] == pytest.approx(top + 0.05, abs=0.01)
    assert abs(out.state_after[-1, 0] - 0.06) < 0.01


def test_unreachable_place_target_raises(world, cat):
    long_table = dataclasses.replace(world, table_length=4.0)
    scene = _place_scene(world, cat, None, 1.6, release=0.05)
    with pytest.raises(UnreachablePoseError, match=r"x=1\.600.*reaches x in \["):
        place(scene, long_table)


def test_bad_inputs_are_named(world, cat):
    good = [_on_table("cube_10", 0.0, cat)]
    with pytest.raises(InputError, match="poses"):
        _pick_scene(["cube_10"], [[0.0, float("nan"), 0.0]])
    with pytest.raises(InputError, match="poses"):
        SideViewScene.nominal("pick", ["cube_10"], np.zeros((1, 2)), 0)
    with pytest.raises(ConfigError, match="cube_11"):
        _pick_scene(["cube_11"], good)
    with pytest.raises(ConfigError, match="unknown side-view scene"):
        load_sideview_scene("pick_everything")
    with pytest.raises(InputError, match="overlap"):
        _pick_scene(["cube_10", "cube_15"], [good[0], _on_table("cube_15", 0.08, cat)])
    with pytest.raises(InputError, match="table"):
        _pick_scene(["cube_10"], [[0.0, 0.03, 0.0]])
    with pytest.raises(InputError, match="target"):
        _pick_scene(["cube_10"], good, target=3)
    with pytest.raises(InputError, match="skill"):
        SideViewScene.nominal("push", ["cube_10"], np.array(good), 0)
    with pytest.raises(InputError, match="release_height"):
        _place_scene(world, cat, None, 0.0, release=0.5)
    with pytest.raises(InputError, match="n must be"):
        sample_sideview_scenes(load_sideview_scene("pick"), 1.5, np.random.default_rng(0))
    with pytest.raises(InputError, match="rng"):
        sample_sideview_scenes(load_sideview_scene("pick"), 1, 0)
    with pytest.raises(InputError, match="scenes"):
        run_skills([], world)
    with pytest.raises(InputError, match="place scene"):
        place(_pick_scene(["cube_10"], good), world)


def test_sampler_and_skills_are_deterministic(world, cat):
    spec = load_sideview_scene("pick")
    a = sample_sideview_scenes(spec, 6, np.random.default_rng(3), world)
    b = sample_sideview_scenes(spec, 6, np.random.default_rng(3), world)
    assert len(a) == 6
    for s, t in zip(a, b, strict=True):
        assert [o.name for o in s.objects] == [o.name for o in t.objects]
        np.testing.assert_array_equal(s.poses, t.poses)
        np.testing.assert_array_equal(s.mass, [cat[o.name].mass for o in s.objects])
        assert s.target == len(s.objects) - 1
    places = sample_sideview_scenes(load_sideview_scene("place"), 4, np.random.default_rng(5))
    for s in places:
        lo, hi = world.place.release_height
        assert s.objects[s.target].name == "cube_10" and lo <= s.release_height <= hi
    runs = [run_skills([a[0], a[1], places[0]], world) for _ in range(2)]
    for x, y in zip(*runs, strict=True):
        np.testing.assert_array_equal(x.objects, y.objects)
        np.testing.assert_array_equal(x.ee_actual, y.ee_actual)
        assert (x.grasped, x.lifted, x.slipped, x.placed) == (
            y.grasped,
            y.lifted,
            y.slipped,
            y.placed,
        )
