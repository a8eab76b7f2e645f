"""Whole push scenes: chain inputs and the monolithic baseline's rows."""

import dataclasses

import numpy as np
import pytest

from probaff.data.generation import GenerateConfig, generate
from probaff.errors import InputError
from probaff.features import (
    Ch6Geometry,
    push_interactions,
    push_scenes,
    scene_effects,
    scene_feature_names,
    scene_features,
)
from probaff.models import ChainScene


@pytest.fixture(scope="module")
def pushes(tmp_path_factory):
    cfg = GenerateConfig("modular_push", 6, seed=3)
    return generate(cfg, tmp_path_factory.mktemp("c6s") / "push", workers=0, progress=False)


def test_scenes_hold_the_hand_and_objects_of_every_push(pushes):
    geo = Ch6Geometry(columns=[])
    scenes = push_scenes(pushes, geometry=geo)
    assert len(scenes) == 6 and scenes.n_objects == 2
    for i in range(len(scenes)):
        scene = ChainScene(  # validates: rigid poses, unit normals, no overlap at the start
            scenes.sizes[i],
            scenes.T_world_obj[i],
            scenes.hand_points[i],
            scenes.hand_normals[i],
            scenes.T_world_hand_start[i],
            scenes.T_world_hand_end[i],
        )
        np.testing.assert_allclose(scene.T_world_obj[:, :2, 3], pushes["state_before"][i, :, :2])
    np.testing.assert_allclose(
        scenes.T_world_obj_after[:, :, :2, 3], pushes["state_after"][..., :2]
    )
    # the push's length and direction: the hand's action frame has y along push_yaw
    yaw = pushes["push_yaw"]
    np.testing.assert_allclose(
        scenes.T_world_action[:, :2, 1], np.column_stack([np.cos(yaw), np.sin(yaw)]), atol=1e-9
    )
    move = scenes.T_world_hand_end[:, :2, 3] - scenes.T_world_hand_start[:, :2, 3]
    np.testing.assert_allclose(np.linalg.norm(move, axis=1), pushes["push_distance"])


def test_scene_effects_agree_with_the_interaction_rows(pushes):
    Y = scene_effects(pushes)
    assert Y.shape == (6, 6)
    hand = push_interactions(pushes, "hand", geometry=Ch6Geometry(columns=[]))
    # o1's (off, along, turn) in the hand's frame are the hand row's (dx, dy, rz)
    np.testing.assert_allclose(Y[:, :3], hand.effect[:, [0, 1, 5]], atol=1e-9)


def test_scene_features_are_in_the_hand_frame(pushes):
    X = scene_features(pushes)
    names = scene_feature_names(2)
    assert X.shape == (6, len(names)) and len(names) == 15 and names[-1] == "push_length"
    np.testing.assert_allclose(X[:, -1], pushes["push_distance"])
    # moving the whole scene (objects and hand) leaves the features unchanged
    shift = np.array([0.05, -0.03])
    arrays = dict(pushes.arrays)
    for name in ("state_before", "state_after"):
        moved = arrays[name].copy()
        moved[..., :2] += shift
        arrays[name] = moved
    arrays["push_origin"] = arrays["push_origin"] + shift
    moved_ds = dataclasses.replace(pushes, arrays=arrays)
    np.testing.assert_allclose(scene_features(moved_ds), X, atol=1e-9)
    np.testing.assert_allclose(scene_effects(moved_ds), scene_effects(pushes), atol=1e-9)
    # o1 lies ahead of the hand, within the push's reach
    assert np.all(X[:, names.index("y_0")] > 0)


def test_bad_input(pushes):
    with pytest.raises(InputError, match="ds must be a PushDataset"):
        push_scenes({"state_before": 1})
    arrays = dict(pushes.arrays)
    bad = arrays["state_before"].copy()
    bad[2, 1, 0] = np.nan
    arrays["state_before"] = bad
    with pytest.raises(InputError, match="state_before holds a non-finite value in row 2"):
        scene_features(dataclasses.replace(pushes, arrays=arrays))
