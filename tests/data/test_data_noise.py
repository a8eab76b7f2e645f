"""Pose-measurement noise in push datasets: determinism, statistics, manifest, resumption."""

import json
import math
import shutil
from dataclasses import replace

import numpy as np
import pytest
from data_helpers import folder_files, read_manifest

from probaff.cli import main
from probaff.data import (
    GROUND_TRUTH_ARRAYS,
    GenerateConfig,
    PoseNoise,
    generate,
    load_dataset,
    observe_poses,
    summarize,
)
from probaff.errors import DatasetError, InputError

NOISE = PoseNoise()  # 3 mm, 1 degree
CLEAN = GenerateConfig(
    scene="two_objects", n=48, seed=11, shard_size=16, cloud_points=16, trajectories=False
)
NOISY = replace(CLEAN, pose_noise=NOISE)
OBSERVED = ("state_before", "state_after", "effect")
PLAN_KEYS = {"scene", "n", "seed", "shard_size", "trajectories", "cloud_points", "cloud_noise"}


@pytest.fixture(scope="module")
def clean(generated):
    return generated(CLEAN, "clean")


@pytest.fixture(scope="module")
def noisy(generated):
    return generated(NOISY, "noisy")


def test_default_is_noise_free_version_6(clean):
    manifest = read_manifest(clean)
    assert manifest["schema_version"] == 6  # the reaction along the path (version 6)
    assert set(manifest["plan"]) == PLAN_KEYS
    ds = load_dataset(clean)
    assert not ds.has_pose_noise
    assert not set(GROUND_TRUTH_ARRAYS) & set(ds.arrays)
    assert ds.true_effect is ds["effect"]
    assert summarize(ds)["pose_noise"] is None


def test_explicit_none_gives_the_same_bytes(clean, tmp_path):
    generate(replace(CLEAN, pose_noise=None), tmp_path / "none", workers=0, progress=False)
    assert folder_files(tmp_path / "none") == folder_files(clean)


def test_noise_changes_only_the_observations(clean, noisy):
    a, b = load_dataset(clean), load_dataset(noisy)
    assert b.has_pose_noise
    assert set(b.arrays) == set(a.arrays) | set(GROUND_TRUTH_ARRAYS)
    for name, arr in a.arrays.items():
        if name in OBSERVED:
            np.testing.assert_array_equal(b["true_" + name], arr)
            assert not np.array_equal(b[name], arr)
        else:
            np.testing.assert_array_equal(b[name], arr, err_msg=name)
    np.testing.assert_array_equal(b.true_effect, a["effect"])


def test_observed_effect_is_the_pushing_frame_difference_of_observed_poses(noisy):
    ds = load_dataset(noisy)
    d = ds["state_after"][..., :2] - ds["state_before"][..., :2]
    c, s = np.cos(ds["push_yaw"])[:, None], np.sin(ds["push_yaw"])[:, None]
    np.testing.assert_allclose(ds["effect"][..., 1], d[..., 0] * c + d[..., 1] * s)
    np.testing.assert_allclose(ds["effect"][..., 0], -d[..., 0] * s + d[..., 1] * c)
    np.testing.assert_allclose(
        ds["effect"][..., 2], ds["state_after"][..., 2] - ds["state_before"][..., 2]
    )


def test_same_seed_same_bytes(noisy, tmp_path):
    generate(NOISY, tmp_path / "again", workers=0, progress=False)
    assert folder_files(tmp_path / "again") == folder_files(noisy)


def test_noise_statistics_match_the_configured_std(noisy):
    ds = load_dataset(noisy)
    err = ds["effect"] - ds["true_effect"]
    pos_std = err[..., :2].std()
    yaw_std = err[..., 2].std()
    assert abs(pos_std / (math.sqrt(2) * NOISE.position_std) - 1) < 0.2
    assert abs(yaw_std / (math.sqrt(2) * NOISE.yaw_std) - 1) < 0.2
    pose_err = ds["state_before"] - ds["true_state_before"]
    assert abs(pose_err[..., :2].std() / NOISE.position_std - 1) < 0.2
    assert abs(np.mean(err)) < 0.2 * NOISE.position_std


def test_observe_poses_statistics_on_many_draws():
    rng = np.random.default_rng(0)
    n, k = 20000, 2
    before = rng.uniform(-0.3, 0.3, (n, k, 3))
    after = before + rng.uniform(-0.1, 0.1, (n, k, 3))
    yaw = rng.uniform(-np.pi, np.pi, n)
    noise = PoseNoise(position_std=0.005, yaw_std=math.radians(2.0))
    ob, _, eff = observe_poses(noise, before, after, yaw, np.random.default_rng(1))
    assert eff.shape == (n, k, 3)
    np.testing.assert_allclose(
        (ob - before).std(axis=(0, 1)), [0.005, 0.005, math.radians(2.0)], rtol=0.03
    )
    ob0, oa0, _ = observe_poses(PoseNoise(0.0, 0.0), before, after, yaw, rng)
    np.testing.assert_array_equal(ob0, before)
    np.testing.assert_array_equal(oa0, after)


def test_manifest_and_summary_record_the_noise(clean, noisy):
    manifest = read_manifest(noisy)
    assert manifest["schema_version"] == 6
    assert manifest["plan"]["pose_noise"] == {"position_std": 0.003, "yaw_std": math.radians(1.0)}
    assert set(manifest["plan"]) == PLAN_KEYS | {"pose_noise"}
    s, s0 = summarize(load_dataset(noisy)), summarize(load_dataset(clean))
    assert s["pose_noise"] == {"position_std_m": 0.003, "yaw_std_rad": math.radians(1.0)}
    # derived statistics describe the exact effects, so noise leaves them unchanged
    for slot in ("o1", "o2"):
        for key in ("mean_abs_effect", "fraction_moved_gt_1cm", "fraction_fell_off"):
            assert s["objects"][slot][key] == s0["objects"][slot][key]
        assert 0.002 < s["objects"][slot]["observed_effect_error_std"]["dy_p_m"] < 0.007
    json.dumps(s)


def test_resume_with_other_noise_is_refused(clean, noisy, tmp_path):
    out = tmp_path / "n"
    shutil.copytree(noisy, out)
    for other in (None, PoseNoise(position_std=0.001)):
        with pytest.raises(DatasetError, match="pose noise"):
            generate(replace(NOISY, pose_noise=other), out, workers=0, resume=True, progress=False)
    out = tmp_path / "c"
    shutil.copytree(clean, out)
    with pytest.raises(DatasetError, match=r"pose noise.*--pose-noise"):
        generate(NOISY, out, workers=0, resume=True, progress=False)


def test_resume_with_the_same_noise_neither_loses_nor_repeats(noisy, tmp_path):
    out = tmp_path / "partial"
    shutil.copytree(noisy, out)
    manifest = read_manifest(out)
    del manifest["shards"]["00001"]
    (out / "manifest.json").write_text(json.dumps(manifest))
    (out / "shards" / "00001.npz").unlink()
    generate(NOISY, out, workers=0, resume=True, progress=False)
    assert folder_files(out) == folder_files(noisy)


def test_inconsistent_datasets_are_refused(clean, noisy, tmp_path):
    out = tmp_path / "v1"
    shutil.copytree(clean, out)
    manifest = read_manifest(out)
    manifest["plan"]["pose_noise"] = NOISE.to_dict()
    manifest["schema_version"] = 1
    (out / "manifest.json").write_text(json.dumps(manifest))
    with pytest.raises(DatasetError, match="schema version 1"):
        load_dataset(out)
    manifest["schema_version"] = 2
    (out / "manifest.json").write_text(json.dumps(manifest))
    with pytest.raises(DatasetError, match="lack the ground-truth arrays"):
        load_dataset(out)
    out = tmp_path / "v2"
    shutil.copytree(noisy, out)
    manifest = read_manifest(out)
    del manifest["plan"]["pose_noise"]
    (out / "manifest.json").write_text(json.dumps(manifest))
    with pytest.raises(DatasetError, match="hold the ground-truth arrays"):
        load_dataset(out)


@pytest.mark.parametrize(
    "kwargs",
    [
        {"position_std": -0.001},
        {"yaw_std": float("nan")},
        {"position_std": float("inf")},
        {"yaw_std": "1"},
        {"position_std": True},
        {"yaw_std": None},
    ],
)
def test_bad_noise_values(kwargs):
    name = next(iter(kwargs))
    with pytest.raises(InputError, match=name):
        PoseNoise(**kwargs)


def test_pose_noise_must_be_a_pose_noise(tmp_path):
    with pytest.raises(InputError, match="pose_noise"):
        generate(replace(CLEAN, pose_noise=(0.003, 1.0)), tmp_path / "x", workers=0, progress=False)


def test_cli_pose_noise(tmp_path, capsys, generate_cli):
    out = tmp_path / "ds"
    flags = ("--seed", "2", "--shard-size", "4", "--pose-noise", "0.002,0.5")
    assert generate_cli("near_obstacle", 4, out, *flags) == 0
    capsys.readouterr()
    assert read_manifest(out)["plan"]["pose_noise"] == {
        "position_std": 0.002,
        "yaw_std": math.radians(0.5),
    }
    assert main(["describe", str(out)]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["pose_noise"]["position_std_m"] == 0.002


@pytest.mark.parametrize("value", ["abc", "0.003", "0.003,1,2", "-1,1", "0.003,nan", ","])
def test_cli_bad_pose_noise(tmp_path, capsys, value, generate_cli):
    code = generate_cli("two_objects", 2, tmp_path / "x", f"--pose-noise={value}")
    assert code == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--pose-noise" in err
    assert not (tmp_path / "x").exists()
