"""Chapter 4 and 5 push features: shapes, groups, invariances and no-contact values.

Covers probaff.features.ch4, probaff.features.ch5 and what they are built from:
probaff.features.featureset, probaff.features.frames and probaff.features._common.
"""

import dataclasses

import numpy as np
import pytest

from probaff.data import GenerateConfig, PushDataset, generate
from probaff.errors import InputError
from probaff.features import TableGeometry, chapter4_features, chapter5_features


@pytest.fixture(scope="module")
def two(tmp_path_factory):
    cfg = GenerateConfig(scene="two_objects", n=24, seed=8, shard_size=24)
    return generate(cfg, tmp_path_factory.mktemp("f") / "two", workers=0, progress=False)


@pytest.fixture(scope="module")
def wall(tmp_path_factory):
    cfg = GenerateConfig(scene="near_wall", n=12, seed=8, shard_size=12)
    return generate(cfg, tmp_path_factory.mktemp("f") / "wall", workers=0, progress=False)


def _moved(ds: PushDataset, angle: float, shift=(0.0, 0.0)) -> PushDataset:
    """The same pushes with the whole scene turned by `angle` about the origin and shifted."""
    c, s = np.cos(angle), np.sin(angle)
    R = np.array([[c, -s], [s, c]])
    t = np.asarray(shift)
    a = {k: v.copy() for k, v in ds.arrays.items()}

    def xy(v):
        return v @ R.T + t

    pts = ds["cloud_points"].astype(np.float64)
    pts[..., :2] = xy(pts[..., :2])
    a["cloud_points"] = pts.astype(np.float32)
    nrm = ds["cloud_normals"].astype(np.float64)
    nrm[..., :2] = nrm[..., :2] @ R.T
    a["cloud_normals"] = nrm.astype(np.float32)
    a["push_origin"] = xy(ds["push_origin"])
    a["push_yaw"] = ds["push_yaw"] + angle
    a["state_before"] = ds["state_before"].copy()
    a["state_before"][..., :2] = xy(ds["state_before"][..., :2])
    a["state_before"][..., 2] += angle
    w = ds["walls"].copy()
    w[..., :2], w[..., 2:] = xy(w[..., :2]), xy(w[..., 2:])
    a["walls"] = w
    return PushDataset(a, ds.object_names, dict(ds.meta))


def test_shapes_and_groups(two):
    f5 = chapter5_features(two)
    assert f5.values.shape == (24, 101)
    assert [f5.select(g).shape[1] for g in ("f_o", "f_c", "f_x")] == [8, 13, 80]
    assert f5.select("f_x", "f_o").shape == (24, 88)
    f4 = chapter4_features(two)
    assert [f4.select(g).shape[1] for g in ("f_o", "f_c", "f_x")] == [13, 42, 576]
    onehot = f4.select("f_x").reshape(24, 144, 4)
    np.testing.assert_array_equal(onehot.sum(-1), 1)
    assert np.all(np.isfinite(f4.values)) and np.all(np.isfinite(f5.values))
    with pytest.raises(InputError, match=r"unknown feature group.*f_o"):
        f5.select("f_z")


@pytest.mark.parametrize("angle", [np.pi / 2, np.pi, -np.pi / 2])
def test_exact_turns_leave_all_features_unchanged(two, wall, angle):
    for ds in (two, wall):
        moved = _moved(ds, angle)
        np.testing.assert_allclose(
            chapter5_features(moved).values, chapter5_features(ds).values, atol=1e-9
        )
        table = TableGeometry(yaw=angle, size=tuple(ds.meta["table_size"]))
        np.testing.assert_allclose(
            chapter4_features(moved, table).values, chapter4_features(ds).values, atol=1e-9
        )


def test_general_rigid_motion_leaves_continuous_features_unchanged(two):
    moved = _moved(two, 0.7, (0.3, -0.2))
    a, b = chapter5_features(two), chapter5_features(moved)
    np.testing.assert_allclose(a.select("f_o"), b.select("f_o"), atol=2e-5)
    a4 = chapter4_features(two)
    b4 = chapter4_features(moved, TableGeometry((0.3, -0.2), 0.7, tuple(two.meta["table_size"])))
    np.testing.assert_allclose(a4.select("f_o"), b4.select("f_o"), atol=2e-5)
    # grid cells can only change where a point lies within float32 rounding of a cell border
    assert (a4.select("f_x") != b4.select("f_x")).mean() < 1e-3


def test_the_wall_is_an_obstacle_in_the_context(wall):
    f4 = chapter4_features(wall).select("f_x").reshape(len(wall), 144, 4)
    assert (f4[..., 1].sum(1) > 0).mean() > 0.5  # most grids see the wall


def test_a_push_that_misses_gives_no_contact_values(wall):
    a = {k: v.copy() for k, v in wall.arrays.items()}
    a["push_yaw"] = wall["push_yaw"] + np.pi  # push away from the object
    a["walls"] = np.zeros((len(wall), 0, 4))
    away = PushDataset(a, wall.object_names, dict(wall.meta))
    f5 = chapter5_features(away).select("f_c")
    d = wall["push_distance"]
    y_f = 0.5 * wall.meta["gripper_opening"]
    np.testing.assert_allclose(f5[:, 0], d)
    np.testing.assert_allclose(f5[:, 1:4], np.stack([0 * d, 0 * d + y_f, d], -1))
    np.testing.assert_allclose(f5[:, 7:10], np.stack([0 * d, 0 * d - y_f, d], -1))
    np.testing.assert_array_equal(f5[:, [4, 5, 6, 10, 11, 12]], 0.0)
    np.testing.assert_array_equal(chapter4_features(away).select("f_c"), 0.0)


def test_contact_distance_tracks_the_gap(two):
    f5 = chapter5_features(two).select("f_c")
    hit = f5[:, 0] < two["push_distance"]
    assert hit.mean() > 0.8  # pushes aim at o1
    # the hand starts 1-4 cm (plus the finger radius) from o1's nearest point
    assert np.all((f5[hit, 0] > 0.0) & (f5[hit, 0] < 0.12))


def test_missing_metadata_and_empty(two):
    meta = {k: v for k, v in two.meta.items() if k != "gripper_opening"}
    with pytest.raises(InputError, match="gripper_opening"):
        chapter5_features(dataclasses.replace(two, meta=meta))
    empty = PushDataset({k: v[:0] for k, v in two.arrays.items()}, two.object_names, two.meta)
    with pytest.raises(InputError, match="no pushes"):
        chapter4_features(empty)
