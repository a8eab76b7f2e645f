"""Push datasets: schema, byte-determinism, serial vs Dask, resumption, corruption.

Covers probaff.data.generation, probaff.data.push_generation, probaff.data.config,
probaff.data.store and probaff.data.schema.
"""

import json

import numpy as np
import pytest
from data_helpers import folder_files

import probaff.data.generation as gen_mod
from probaff.data import GenerateConfig, generate, load_dataset, summarize
from probaff.data.schema import SCHEMA_VERSION, PushDataset
from probaff.errors import DatasetError, InputError

CFG = GenerateConfig(scene="two_objects", n=20, seed=4, shard_size=8, cloud_points=32)


@pytest.fixture(scope="module")
def reference(generated):
    return generated(CFG, "ref")


def test_schema_and_contents(reference):
    ds = load_dataset(reference)
    assert len(ds) == 20 and ds.n_objects == 2
    assert ds["effect"].shape == (20, 2, 3)
    assert ds["cloud_points"].shape == (20, 2, 32, 3)
    assert ds["q_waypoints"].shape[2] == 6
    assert ds.has_trajectories and ds["traj_objects"].shape[2] == 2
    assert ds.meta["scene"] == "two_objects" and ds.meta["seed"] == 4
    assert np.all(ds["hand_contact"][:, 0])
    # the effect is the pose change expressed in the pushing frame
    d = ds["state_after"][:, 0, :2] - ds["state_before"][:, 0, :2]
    c, s = np.cos(ds["push_yaw"]), np.sin(ds["push_yaw"])
    np.testing.assert_allclose(ds["effect"][:, 0, 1], d[:, 0] * c + d[:, 1] * s)
    np.testing.assert_allclose(ds["effect"][:, 0, 0], -d[:, 0] * s + d[:, 1] * c)


def test_same_seed_same_bytes(reference, tmp_path):
    generate(CFG, tmp_path / "again", workers=0, progress=False)
    assert folder_files(tmp_path / "again") == folder_files(reference)


def test_dask_matches_serial(reference, tmp_path):
    generate(CFG, tmp_path / "dask", workers=2, progress=False)
    assert folder_files(tmp_path / "dask") == folder_files(reference)


def test_other_seed_differs(reference, tmp_path):
    from dataclasses import replace

    ds = generate(replace(CFG, seed=5), tmp_path / "s5", workers=0, progress=False)
    assert not np.array_equal(ds["effect"], load_dataset(reference)["effect"])


def test_killed_run_resumes_without_loss_or_duplication(reference, tmp_path, monkeypatch):
    out = tmp_path / "crash"
    real = gen_mod.make_shard
    calls = []

    def dying(config, index):
        if len(calls) == 2:
            raise KeyboardInterrupt  # the process is killed while computing the third shard
        calls.append(index)
        return real(config, index)

    monkeypatch.setattr(gen_mod, "make_shard", dying)
    with pytest.raises(KeyboardInterrupt):
        generate(CFG, out, workers=0, progress=False)
    monkeypatch.setattr(gen_mod, "make_shard", real)
    manifest = json.loads((out / "manifest.json").read_text())
    assert sorted(manifest["shards"]) == ["00000", "00001"]
    with pytest.raises(DatasetError, match="incomplete"):
        load_dataset(out)
    with pytest.raises(DatasetError, match="--resume"):
        generate(CFG, out, workers=0, progress=False)
    generate(CFG, out, workers=0, resume=True, progress=False)
    assert folder_files(out) == folder_files(reference)


def test_shard_written_before_manifest_is_adopted(reference, tmp_path):
    import shutil

    out = tmp_path / "orphan"
    shutil.copytree(reference, out)
    manifest = json.loads((out / "manifest.json").read_text())
    del manifest["shards"]["00001"]  # crash between the shard's rename and the manifest's
    (out / "manifest.json").write_text(json.dumps(manifest))
    (out / "shards" / ".00002.npz.tmp-999").write_bytes(b"partial")
    generate(CFG, out, workers=0, resume=True, progress=False)
    assert folder_files(out) == folder_files(reference)


def test_resume_with_other_options_is_refused(reference, tmp_path):
    import shutil
    from dataclasses import replace

    out = tmp_path / "other"
    shutil.copytree(reference, out)
    with pytest.raises(DatasetError, match="was started with"):
        generate(replace(CFG, seed=99), out, workers=0, resume=True, progress=False)


def test_truncated_shard_is_detected(reference, tmp_path):
    import shutil

    out = tmp_path / "trunc"
    shutil.copytree(reference, out)
    shard = out / "shards" / "00001.npz"
    shard.write_bytes(shard.read_bytes()[:-100])
    with pytest.raises(DatasetError, match="checksum"):
        load_dataset(out)


def test_corrupt_manifest_and_wrong_version(reference, tmp_path, copy_dataset):
    out = copy_dataset(reference, tmp_path / "ver", schema_version=SCHEMA_VERSION + 1)
    with pytest.raises(DatasetError, match="schema version"):
        load_dataset(out)
    (out / "manifest.json").write_text('{"format": "probaff-push-dat')
    with pytest.raises(DatasetError, match="truncated or not JSON"):
        load_dataset(out)
    with pytest.raises(DatasetError, match="not a probaff dataset"):
        load_dataset(tmp_path)


@pytest.mark.parametrize(
    "field,value",
    [("n", 0), ("n", -5), ("shard_size", 0), ("seed", -1), ("cloud_noise", float("nan"))],
)
def test_bad_generate_options(tmp_path, field, value):
    from dataclasses import replace

    with pytest.raises(InputError, match=field):
        generate(replace(CFG, **{field: value}), tmp_path / "x", workers=0, progress=False)


def test_unknown_scene_fails_before_work(tmp_path):
    from dataclasses import replace

    with pytest.raises(InputError, match="unknown scene"):
        generate(replace(CFG, scene="kitchen"), tmp_path / "x", workers=0, progress=False)


def test_summary(reference):
    s = summarize(load_dataset(reference))
    assert s["n_pushes"] == 20
    o1 = s["objects"]["o1"]
    assert o1["fraction_moved_gt_1cm"] > 0.8
    assert o1["mean_abs_effect"]["dz_p_m"] > 0.1
    assert 0 <= s["objects"]["o2"]["fraction_moved_gt_1cm"] <= 1
    json.dumps(s)


def test_dataset_validation():
    with pytest.raises(DatasetError, match="missing arrays"):
        PushDataset({"effect": np.zeros((2, 1, 3))}, ["a"])


def test_existing_scheduler_gives_the_same_bytes(reference, tmp_path):
    from dask.distributed import LocalCluster

    with LocalCluster(
        n_workers=1, threads_per_worker=1, processes=True, dashboard_address=None
    ) as cluster:
        generate(CFG, tmp_path / "sched", scheduler=cluster.scheduler_address, progress=False)
    assert folder_files(tmp_path / "sched") == folder_files(reference)


def _copy(reference, out):
    import shutil

    shutil.copytree(reference, out)
    return out


def test_flipped_shard_byte_fails_its_checksum(reference, tmp_path):
    out = _copy(reference, tmp_path / "flip")
    shard = out / "shards" / "00001.npz"
    data = bytearray(shard.read_bytes())
    data[len(data) // 2] ^= 0x01
    shard.write_bytes(bytes(data))
    with pytest.raises(
        DatasetError, match=r"shard .*00001\.npz does not match its checksum.*--resume"
    ):
        load_dataset(out)


def test_dataset_without_checksums_loads_with_a_warning_and_damage_is_still_caught(
    reference, tmp_path
):
    out = _copy(reference, tmp_path / "old")
    manifest = json.loads((out / "manifest.json").read_text())
    for entry in manifest["shards"].values():
        del entry["sha256"]
    (out / "manifest.json").write_text(json.dumps(manifest))
    with pytest.warns(UserWarning, match="3 of the 3 shards .* have no checksum"):
        ds = load_dataset(out)
    expected = load_dataset(reference)
    for name in expected.arrays:
        np.testing.assert_array_equal(ds[name], expected[name])

    # without a checksum, a damaged shard is refused by the zip format or the schema, never
    # read silently nor reported with a raw exception
    shard = out / "shards" / "00001.npz"
    clean = shard.read_bytes()
    for at in range(0, len(clean), max(1, len(clean) // 40)):
        data = bytearray(clean)
        data[at] ^= 0xFF
        shard.write_bytes(bytes(data))
        try:
            with pytest.warns(UserWarning, match="no checksum"):
                damaged = load_dataset(out)
        except DatasetError as exc:
            assert "00001.npz" in str(exc) and "--resume" in str(exc), str(exc)
        else:
            for name in expected.arrays:
                np.testing.assert_array_equal(damaged[name], expected[name])
    shard.write_bytes(b"PK\x03\x04" + clean[4:100])
    with (
        pytest.warns(UserWarning),
        pytest.raises(DatasetError, match=r"shard .*00001\.npz is corrupt .*--resume"),
    ):
        load_dataset(out)


def test_unreadable_shards_and_malformed_manifests_are_dataset_errors(reference, tmp_path):
    out = _copy(reference, tmp_path / "bad")
    shard = out / "shards" / "00002.npz"
    shard.unlink()
    shard.mkdir()
    with pytest.raises(DatasetError, match=r"cannot read shard .*00002\.npz .*--resume"):
        load_dataset(out)
    shard.rmdir()
    with pytest.raises(DatasetError, match=r"shard .*00002\.npz is missing"):
        load_dataset(out)

    good = json.loads((reference / "manifest.json").read_text())
    for change in (
        {"plan": [1]},
        {"plan": {**good["plan"], "shard_size": 0}},
        {"object_names": "book"},
        {"meta": None},
        {"shards": {"00000": 5}},
        {"shards": {"00000": {"rows": "8", "sha256": "x"}}},
    ):
        (out / "manifest.json").write_text(json.dumps({**good, **change}))
        with pytest.raises(DatasetError, match=r"manifest\.json is malformed: its .*regenerate"):
            load_dataset(out)
    (out / "manifest.json").unlink()
    (out / "manifest.json").mkdir()
    with pytest.raises(DatasetError, match=r"no manifest\.json"):
        load_dataset(out)
