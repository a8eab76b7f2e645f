"""Candidate pushes without outcomes: the feature functions read them like a dataset."""

import numpy as np
import pytest

from probaff.data.generation import GenerateConfig, make_shard
from probaff.data.queries import QUERY_ARRAYS, PushQueries, world_meta
from probaff.data.schema import PushDataset
from probaff.errors import InputError
from probaff.features import chapter4_features, chapter5_features
from probaff.sim.specs import load_catalogue
from probaff.sim.tabletop_config import load_tabletop


@pytest.fixture(scope="module")
def shard():
    return make_shard(GenerateConfig("two_objects", 6, shard_size=6, trajectories=False), 0)


def test_features_of_queries_equal_those_of_the_dataset(shard):
    world = load_tabletop()
    ds = PushDataset(shard, sorted(load_catalogue()), world_meta(world))
    q = PushQueries({k: shard[k] for k in QUERY_ARRAYS}, world_meta(world))
    for features in (chapter4_features, chapter5_features):
        assert np.array_equal(features(ds).values, features(q).values)


def test_from_states_moves_one_sensed_cloud_rigidly(shard):
    cat = load_catalogue()
    objs = [cat[n] for n in ("cracker_box", "wood_block")]
    poses = np.array([[[0.0, 0.0, 0.0], [0.3, 0.1, 0.5]], [[0.1, -0.2, 1.0], [0.3, 0.1, 0.5]]])
    q = PushQueries.from_states(
        objs,
        poses,
        np.array([[-0.2, 0.0], [-0.1, -0.2]]),
        np.array([0.0, 0.3]),
        0.25,
        load_tabletop(),
        np.random.default_rng(0),
        cloud_noise=0.0,
    )
    pts = q["cloud_points"].astype(float)
    assert pts.shape == (2, 2, 256, 3) and len(q) == 2 and q.n_objects == 2
    # object 0 moved by (0.1, -0.2) and turned by 1 rad between the two states
    c, s = np.cos(1.0), np.sin(1.0)
    want = pts[0, 0, :, :2] @ np.array([[c, s], [-s, c]]) + [0.1, -0.2]
    assert np.allclose(pts[1, 0, :, :2], want, atol=1e-5)
    assert np.allclose(pts[1, 1], pts[0, 1])  # object 1 did not move
    assert np.allclose(pts[1, :, :, 2], pts[0, :, :, 2])  # heights do not change
    n = q["cloud_normals"]
    assert np.allclose(np.linalg.norm(n, axis=-1), 1, atol=1e-5)


def test_bad_queries_name_the_array():
    world = load_tabletop()
    obj = [load_catalogue()["book"]]
    cases = [  # (message, poses, push origins, push yaws, push distance)
        ("poses contains 1 NaN", np.array([[0, np.nan, 0]]), np.zeros((1, 2)), np.zeros(1), 0.1),
        (
            "push_distance must be a finite number > 0",
            np.zeros((1, 3)),
            np.zeros((1, 2)),
            np.zeros(1),
            0.0,
        ),
        ("push_yaw has shape", np.zeros((1, 3)), np.zeros((2, 2)), np.zeros(3), 0.1),
        ("hold no pushes", np.zeros((1, 3)), np.zeros((0, 2)), np.zeros(0), 0.1),
    ]
    for match, poses, origins, yaws, distance in cases:
        with pytest.raises(InputError, match=match):
            PushQueries.from_states(
                obj, poses, origins, yaws, distance, world, np.random.default_rng(0)
            )
    with pytest.raises(InputError, match="lack arrays"):
        PushQueries({"push_yaw": np.zeros(1)})
