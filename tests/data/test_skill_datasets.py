"""Side-view skill datasets: schema, determinism, Dask, resumption, versions and the CLI.

Covers probaff.data.skill_generation, probaff.data.skill_schema and probaff.data.summary.
"""

import json
import math
import shutil
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from data_helpers import folder_files, read_manifest

import probaff.data.generation as gen_mod
from probaff.cli import main
from probaff.data import (
    NO_OBJECT,
    GenerateConfig,
    PoseNoise,
    PushDataset,
    SkillDataset,
    generate,
    generate_skills,
    load_dataset,
    load_skill_dataset,
    make_shard,
    scene_kind,
)
from probaff.data.skill_generation import resample_times
from probaff.data.store import read_shard
from probaff.errors import ConfigError, DatasetError, InputError
from probaff.sim import load_sideview, registry
from probaff.sim.registry import world_kind

PICK = GenerateConfig(scene="pick", n=24, seed=3, shard_size=8)
TINY = GenerateConfig(scene="pick", n=4, seed=8, shard_size=2)
PUSH = GenerateConfig(
    scene="two_objects", n=2, seed=1, shard_size=2, cloud_points=8, trajectories=False
)
PUSH_PLAN_KEYS = {"scene", "n", "seed", "shard_size", "trajectories", "cloud_points", "cloud_noise"}
WORLD = load_sideview()
SPAN = WORLD.gripper.span


def _edit_manifest(root: Path, **changes) -> None:
    m = read_manifest(root)
    m.update(changes)
    (root / "manifest.json").write_text(json.dumps(m))


@pytest.fixture(scope="module")
def pick(generated):
    return generated(PICK, "pick", kind="skill")


@pytest.fixture(scope="module")
def tiny(generated):
    return generated(TINY, "tiny", kind="skill")


def test_pick_dataset_shapes_and_manifest(pick):
    ds = load_skill_dataset(pick)
    assert isinstance(ds, SkillDataset) and len(ds) == 24 and ds.skill == "pick"
    K, T, W = ds.meta["n_objects"], ds.meta["n_samples"], ds.meta["n_waypoints"]
    assert (K, ds.n_objects, ds.n_samples) == (2, 2, T)
    assert ds["size"].shape == (24, K, 3) and ds["state_after"].shape == (24, K, 3)
    assert ds["traj_objects"].shape == (24, T, K, 3) and ds["ee_actual"].shape == (24, T, 3)
    assert ds["opening_commanded"].shape == (24, T) and ds["q_waypoints"].shape[:2] == (24, W)
    assert ds["q_waypoints"].shape[2] == 6
    assert ds.object_names == sorted(ds.object_names) and "cube_10" in ds.object_names
    manifest = read_manifest(pick)
    assert (manifest["kind"], manifest["schema_version"]) == ("skill", 3)
    assert manifest["plan"] == {
        "scene": "pick",
        "n": 24,
        "seed": 3,
        "shard_size": 8,
        "trajectories": True,
        "record_rate": WORLD.physics.record_rate,
    }
    assert sorted(manifest["shards"]) == ["00000", "00001", "00002"]


def test_pick_flags_follow_the_gripper_span(pick):
    ds = load_skill_dataset(pick)
    rows = np.arange(len(ds))
    target = ds["target"].astype(int)
    width = ds["size"][rows, target, 0]
    mass = ds["mass"][rows, target]
    too_wide = width > SPAN + 1e-9
    graspable = (width < SPAN - 0.01) & (mass < 1.0)
    assert too_wide.sum() >= 3 and graspable.sum() >= 3  # both kinds are in this sample
    assert not ds["lifted"][too_wide].any() and not ds["grasped"][too_wide].any()
    assert ds["lifted"][graspable].all() and ds["grasped"][graspable].all()
    assert not ds["placed"].any() and np.all(ds["support"] == -1)
    np.testing.assert_array_equal(ds["release_height"], 0.0)
    # a lifted object ends about the lift higher; one too wide stays where it was
    rise = ds["state_after"][rows, target, 1] - ds["state_before"][rows, target, 1]
    assert np.all(rise[ds["lifted"]] > 0.5 * WORLD.pick.lift)
    assert np.all(np.abs(rise[too_wide]) < 0.02)
    # the picked object is the last present slot; empty slots are padding
    present = ds.present
    assert np.all(present[rows, target]) and np.all(present[:, 0])
    assert np.all(target == present.sum(axis=1) - 1)
    assert (~present).any()  # some scenes hold a single object
    empty = ~present
    assert np.all(ds["object_ids"][empty] == NO_OBJECT)
    for name in ("size", "mass", "state_before", "state_after"):
        assert np.all(ds[name][empty] == 0), name
    assert np.all(ds["traj_objects"].transpose(0, 2, 1, 3)[empty] == 0)
    # the aim is the grasp point: grasp_fraction of the object's height
    bottom = ds["state_before"][rows, target, 1] - 0.5 * ds["size"][rows, target, 2]
    z_aim = bottom + WORLD.pick.grasp_fraction * ds["size"][rows, target, 2]
    np.testing.assert_allclose(ds["target_xz"][:, 1], z_aim, atol=0.01)


def test_trajectories_are_resampled_and_padded_with_the_last_sample(pick):
    ds = load_skill_dataset(pick)
    T, rate = ds.n_samples, ds.meta["record_rate"]
    lengths = ds["traj_length"]
    assert lengths.min() >= 2 and lengths.max() <= T
    assert lengths.min() < lengths.max()  # skills of different lengths share one T
    for i, L in enumerate(lengths):
        t = ds["traj_time"][i]
        assert t[0] == 0.0 and np.all(np.diff(t[:L]) > 0)
        np.testing.assert_allclose(t[: L - 1], np.arange(L - 1) / rate)
        assert t[L - 1] - t[L - 2] <= 1.0 / rate + 1e-9
        for name in ("traj_time", "ee_commanded", "ee_actual", "opening_actual", "traj_objects"):
            tail = ds[name][i, L:]
            assert np.all(tail == ds[name][i, L - 1]), name
        n_q = ds["n_waypoints"][i]
        assert np.all(ds["q_waypoints"][i, n_q:] == ds["q_waypoints"][i, n_q - 1])
    # the trajectories start at state_before and end at state_after
    last = lengths - 1
    np.testing.assert_allclose(ds["traj_objects"][:, 0], ds["state_before"], atol=1e-5)
    np.testing.assert_allclose(
        ds["traj_objects"][np.arange(len(ds)), last], ds["state_after"], atol=1e-5
    )
    # the fingers open fully, then close; the commanded opening starts at the span
    np.testing.assert_allclose(ds["opening_commanded"][:, 0], SPAN, atol=1e-6)
    assert np.all(ds["opening_commanded"][np.arange(len(ds)), last] == 0)


def test_same_seed_same_bytes_and_shards_are_independent(pick, tmp_path):
    generate_skills(PICK, tmp_path / "again", workers=0, progress=False)
    assert folder_files(tmp_path / "again") == folder_files(pick)
    manifest = read_manifest(pick)
    arrays = make_shard(PICK.validate(), 2)  # shard 2 alone, without shards 0 and 1
    stored = read_shard(pick, 2, manifest["shards"]["00002"]["sha256"])
    assert arrays.keys() == stored.keys()
    for name in arrays:
        np.testing.assert_array_equal(arrays[name], stored[name], err_msg=name)
    other = load_skill_dataset(generate_skills_dir(replace(PICK, seed=4), tmp_path / "s4"))
    assert not np.array_equal(other["state_before"], load_skill_dataset(pick)["state_before"])


def generate_skills_dir(config: GenerateConfig, out: Path) -> Path:
    generate_skills(config, out, workers=0, progress=False)
    return out


def test_dask_matches_serial(tiny, tmp_path):
    generate_skills(TINY, tmp_path / "dask", workers=2, progress=False)
    assert folder_files(tmp_path / "dask") == folder_files(tiny)


def test_resume_recomputes_only_the_deleted_shard(pick, tmp_path, monkeypatch):
    out = tmp_path / "resume"
    shutil.copytree(pick, out)
    (out / "shards" / "00001.npz").unlink()
    with pytest.raises(DatasetError, match="missing"):
        load_skill_dataset(out)
    with pytest.raises(DatasetError, match="--resume"):
        generate_skills(PICK, out, workers=0, progress=False)
    real, calls = gen_mod.make_shard, []

    def counting(config, index):
        calls.append(index)
        return real(config, index)

    monkeypatch.setattr(gen_mod, "make_shard", counting)
    generate_skills(PICK, out, workers=0, resume=True, progress=False)
    assert calls == [1]
    assert folder_files(out) == folder_files(pick)


def test_corrupt_shard_is_detected_and_repaired_on_resume(pick, tmp_path):
    out = tmp_path / "corrupt"
    shutil.copytree(pick, out)
    shard = out / "shards" / "00002.npz"
    data = bytearray(shard.read_bytes())
    data[len(data) // 2] ^= 0xFF
    shard.write_bytes(bytes(data))
    with pytest.raises(DatasetError, match="checksum"):
        load_skill_dataset(out)
    generate_skills(PICK, out, workers=0, resume=True, progress=False)
    assert folder_files(out) == folder_files(pick)


def test_resume_with_other_options_is_refused(tiny, tmp_path):
    out = tmp_path / "other"
    shutil.copytree(tiny, out)
    for other in (replace(TINY, seed=9), replace(TINY, record_rate=10.0)):
        with pytest.raises(DatasetError, match="was started with"):
            generate_skills(other, out, workers=0, resume=True, progress=False)
    with pytest.raises(DatasetError, match="skill dataset"):
        generate(replace(PUSH, n=4), out, workers=0, resume=True, progress=False)


@pytest.mark.parametrize("noise,version", [(None, 6), (PoseNoise(), 6)])
def test_push_datasets_are_written_and_read_as_before(tmp_path, tiny, noise, version):
    out = tmp_path / "push"
    ds = generate(replace(PUSH, pose_noise=noise), out, workers=0, progress=False)
    manifest = read_manifest(out)
    assert manifest["schema_version"] == version and "kind" not in manifest
    keys = PUSH_PLAN_KEYS | ({"pose_noise"} if noise else set())
    assert set(manifest["plan"]) == keys
    again = load_dataset(out)
    assert isinstance(again, PushDataset) and len(again) == len(ds) == 2
    assert again.has_pose_noise == (noise is not None)
    np.testing.assert_array_equal(again["effect"], ds["effect"])
    with pytest.raises(DatasetError, match=r"push dataset.*load_dataset"):
        load_skill_dataset(out)
    with pytest.raises(DatasetError, match=r"skill dataset.*load_skill_dataset"):
        load_dataset(tiny)


def test_unknown_version_or_kind_is_refused(tiny, tmp_path):
    readable = "push datasets of schema versions 1, 2, 6 and skill datasets of schema version 3"
    cases = [
        ({"kind": "grasp"}, "kind 'grasp'"),
        ({"schema_version": 4}, "skill dataset of schema version 4"),
        ({"schema_version": 2}, "skill dataset of schema version 2"),
        ({"kind": "push"}, "push dataset of schema version 3"),
    ]
    for i, (changes, what) in enumerate(cases):
        out = tmp_path / f"v{i}"
        shutil.copytree(tiny, out)
        _edit_manifest(out, **changes)
        for load in (load_dataset, load_skill_dataset):
            with pytest.raises(DatasetError, match=what) as err:
                load(out)
            assert readable in str(err.value) and "regenerate" in str(err.value)


@pytest.mark.parametrize(
    "field,value",
    [
        ("n", 0),
        ("n", 1.5),
        ("n", "8"),
        ("shard_size", 0),
        ("seed", -1),
        ("record_rate", 0.0),
        ("record_rate", float("nan")),
    ],
)
def test_bad_config_values(tmp_path, field, value):
    with pytest.raises(InputError, match=field):
        generate_skills(replace(TINY, **{field: value}), tmp_path / "x", workers=0, progress=False)
    assert not (tmp_path / "x").exists()


def test_unknown_and_misused_scenes(tmp_path, monkeypatch):
    with pytest.raises(InputError, match=r"unknown scene 'kitchen'.*two_objects.*pick") as err:
        generate_skills(replace(TINY, scene="kitchen"), tmp_path / "x", progress=False)
    assert not isinstance(err.value, ConfigError)  # a bad argument, not a broken world file
    with pytest.raises(InputError, match="scene must be"):
        scene_kind(3)
    assert (scene_kind("pick"), scene_kind("place"), scene_kind("two_objects")) == (
        "skill",
        "skill",
        "push",
    )
    with pytest.raises(InputError, match=r"probaff\.data\.generate "):
        generate_skills(PUSH, tmp_path / "x", progress=False)
    with pytest.raises(InputError, match="pose_noise"):
        generate_skills(replace(TINY, pose_noise=PoseNoise()), tmp_path / "x", progress=False)
    with pytest.raises(InputError, match="record_rate"):
        generate(replace(PUSH, record_rate=10.0), tmp_path / "x", progress=False)
    assert not (tmp_path / "x").exists()
    twice = tmp_path / "twice"
    twice.mkdir()
    (twice / "pick.yaml").write_text("name: pick\n")
    monkeypatch.setitem(
        registry._WORLDS.entries, "tabletop", replace(world_kind("tabletop"), scenes=twice)
    )
    with pytest.raises(ConfigError, match=r"twice/pick\.yaml.*sideview_scenes/pick\.yaml"):
        generate_skills(TINY, tmp_path / "x", progress=False)


def test_generate_makes_the_dataset_of_the_scenes_kind(tiny, tmp_path):
    ds = generate(TINY, tmp_path / "one", workers=0, progress=False)
    assert isinstance(ds, SkillDataset) and ds.rows_label == "picks"
    assert folder_files(tmp_path / "one") == folder_files(tiny)


def test_place_dataset_without_trajectories(tmp_path):
    cfg = GenerateConfig(scene="place", n=6, seed=2, shard_size=3, trajectories=False)
    ds = generate_skills(cfg, tmp_path / "place", workers=0, progress=False)
    assert ds.skill == "place" and not ds.has_trajectories and ds.n_samples == 0
    assert "traj_time" not in ds.arrays
    assert read_manifest(tmp_path / "place")["plan"]["trajectories"] is False
    rows = np.arange(6)
    target, support = ds["target"].astype(int), ds["support"].astype(int)
    assert np.all(target == ds.present.sum(axis=1) - 1)  # the held cube is the last object
    assert {ds.object_names[i] for i in ds["object_ids"][rows, target]} == {"cube_10"}
    assert np.all((support == -1) | (support == target - 1))
    low, high = WORLD.place.release_height
    assert np.all((ds["release_height"] >= low) & (ds["release_height"] <= high))
    assert ds["grasped"].all() and not ds["lifted"].any()
    placed = ds["placed"]
    assert placed.any() and not placed.all()  # some cubes fall off their supports
    # a placed cube ends on its target: the table (z = 0) or its support's top
    top = np.where(
        support < 0,
        0.0,
        ds["state_after"][rows, support, 1] + 0.5 * ds["size"][rows, support, 2],
    )
    np.testing.assert_allclose(
        ds["state_after"][rows, target, 1][placed], (top + 0.05)[placed], atol=0.01
    )
    np.testing.assert_allclose(ds["target_xz"][:, 1], np.where(support < 0, 0.0, top), atol=0.01)


def test_manifest_traj_flag_must_match_the_shards(tiny, tmp_path):
    out = tmp_path / "flag"
    shutil.copytree(tiny, out)
    m = read_manifest(out)
    m["plan"]["trajectories"] = False
    (out / "manifest.json").write_text(json.dumps(m))
    with pytest.raises(DatasetError, match="hold the trajectory arrays"):
        load_skill_dataset(out)


def test_schema_validation(tiny):
    ds = load_skill_dataset(tiny)
    names = ds.object_names
    with pytest.raises(DatasetError, match="missing arrays"):
        SkillDataset({"object_ids": ds["object_ids"]}, names)
    partial = {k: v for k, v in ds.arrays.items() if k != "ee_actual"}
    with pytest.raises(DatasetError, match="trajectory arrays"):
        SkillDataset(partial, names)
    with pytest.raises(DatasetError, match="'mass' has dtype float32"):
        SkillDataset({**ds.arrays, "mass": ds["mass"].astype(np.float32)}, names)
    with pytest.raises(DatasetError, match="'size' has shape"):
        SkillDataset({**ds.arrays, "size": ds["size"][:, :1]}, names)
    with pytest.raises(DatasetError, match="target"):
        SkillDataset({**ds.arrays, "target": np.full(len(ds), 5, dtype=np.int16)}, names)
    with pytest.raises(DatasetError, match="traj_length"):
        SkillDataset({**ds.arrays, "traj_length": ds["traj_length"] + 1000}, names)
    both = SkillDataset.concatenate([ds, ds])
    assert len(both) == 2 * len(ds)
    np.testing.assert_array_equal(both["traj_objects"][len(ds) :], ds["traj_objects"])
    bare = SkillDataset(
        {k: v for k, v in ds.arrays.items() if not k.startswith(("traj", "ee", "open"))}, names
    )
    with pytest.raises(DatasetError, match="with and without trajectories"):
        SkillDataset.concatenate([ds, bare])


def test_resample_times():
    np.testing.assert_allclose(resample_times(1.0, 20.0), np.arange(21) / 20.0)
    t = resample_times(1.02, 20.0)
    assert len(t) == 22 and t[-1] == 1.02 and t[-2] == 1.0
    assert len(resample_times(0.0, 20.0)) == 1


def test_cli_generates_picks_and_lists_scenes(tmp_path, capsys):
    out = tmp_path / "cli"
    args = ["generate", "--scene", "pick", "--n", "4", "--seed", "8", "--out", str(out)]
    assert main([*args, "--shard-size", "2", "--workers", "0", "--quiet"]) == 0
    assert "wrote 4 picks" in capsys.readouterr().out
    ds = load_skill_dataset(out)
    assert len(ds) == 4 and ds.meta["scene"] == "pick"
    assert main(["scenes"]) == 0
    listing = capsys.readouterr().out
    for name in ("two_objects", "pick", "pick_beside", "place"):
        assert any(line.split()[0] == name for line in listing.splitlines()), name
    assert "side view, place" in listing


@pytest.mark.parametrize(
    "extra,message",
    [
        (["--scene", "garage"], "unknown scene 'garage'"),
        (["--scene", "pick", "--pose-noise", "0.003,1"], "pose_noise"),
        (["--scene", "pick", "--record-rate", "-5"], "record_rate"),
        (["--scene", "two_objects", "--record-rate", "10"], "record_rate"),
    ],
)
def test_cli_user_errors_print_one_line(tmp_path, capsys, extra, message):
    out = tmp_path / "bad"
    code = main(["generate", *extra, "--n", "2", "--out", str(out), "--workers", "0", "--quiet"])
    assert code == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and message in err and err.startswith("probaff generate:")
    assert not out.exists()


def test_record_rate_sets_the_trajectory_samples(tmp_path):
    cfg = replace(TINY, n=2, record_rate=10.0)
    ds = generate_skills(cfg, tmp_path / "r10", workers=0, progress=False)
    default = load_skill_dataset(generate_skills_dir(replace(TINY, n=2), tmp_path / "r20"))
    assert ds.meta["record_rate"] == 10.0
    assert math.isclose(ds.n_samples, default.n_samples / 2, abs_tol=1.0)
    np.testing.assert_array_equal(ds["state_after"], default["state_after"])
    np.testing.assert_allclose(ds["traj_time"][:, 1], 0.1)


def test_cli_describes_pick_and_place_datasets(tiny, tmp_path, capsys):
    assert main(["describe", str(tiny)]) == 0
    pick = json.loads(capsys.readouterr().out)
    ds = load_skill_dataset(tiny)
    assert pick["skill"] == "pick" and pick["scene"] == "pick" and pick["n_samples"] == 4
    assert set(pick["outcomes"]) == {"fraction_grasped", "fraction_lifted", "fraction_slipped"}
    assert pick["outcomes"]["fraction_lifted"] == pytest.approx(ds["lifted"].mean())
    assert sum(pick["target_counts"].values()) == 4
    assert pick["has_trajectories"] and pick["n_trajectory_samples"] == ds.n_samples
    assert pick["release_height_m"] is None and pick["fraction_on_table_support"] is None
    rows = np.arange(4)
    target = ds["target"].astype(int)
    lift = (ds["state_after"] - ds["state_before"])[rows, target, 1]
    assert pick["target"]["mean_effect"]["dz_m"] == pytest.approx(lift.mean())
    assert set(pick["objects"]) == {f"o{k + 1}" for k in range(ds.n_objects)}

    out = tmp_path / "place"
    args = ["generate", "--scene", "place", "--n", "4", "--seed", "2", "--out", str(out)]
    assert main([*args, "--shard-size", "2", "--workers", "0", "--no-trajectories", "--quiet"]) == 0
    capsys.readouterr()
    assert main(["describe", str(out)]) == 0
    place = json.loads(capsys.readouterr().out)
    assert place["skill"] == "place" and place["n_samples"] == 4
    assert set(place["outcomes"]) == {"fraction_grasped", "fraction_slipped", "fraction_placed"}
    assert place["target_counts"] == {"cube_10": 4} and not place["has_trajectories"]
    low, high = WORLD.place.release_height
    assert low <= place["release_height_m"]["min"] <= place["release_height_m"]["max"] <= high
    assert 0.0 <= place["fraction_on_table_support"] <= 1.0


def test_skill_dataset_without_checksums_loads_with_a_warning(tiny, tmp_path):
    out = tmp_path / "unchecked"
    shutil.copytree(tiny, out)
    manifest = read_manifest(out)
    for entry in manifest["shards"].values():
        del entry["sha256"]
    (out / "manifest.json").write_text(json.dumps(manifest))
    with pytest.warns(UserWarning, match="2 of the 2 shards .* have no checksum"):
        ds = load_skill_dataset(out)
    np.testing.assert_array_equal(ds["state_after"], load_skill_dataset(tiny)["state_after"])
    shard = out / "shards" / "00001.npz"
    data = bytearray(shard.read_bytes())
    data[len(data) // 2] ^= 0xFF
    shard.write_bytes(bytes(data))
    with (
        pytest.warns(UserWarning, match="no checksum"),
        pytest.raises(DatasetError, match=r"shard .*00001\.npz is corrupt .*--resume"),
    ):
        load_skill_dataset(out)
