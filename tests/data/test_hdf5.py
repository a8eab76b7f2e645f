"""HDF5 in and out: the documented layout, byte-identical round trips, other programs' files
and bad files.

Covers probaff.data.hdf5.
"""

import hashlib
import json
from pathlib import Path

import h5py
import numpy as np
import pytest
import torch
from data_helpers import folder_files

from probaff._threads import limit_threads
from probaff.data import (
    SKILL_OBSERVATION_ARRAYS,
    GenerateConfig,
    PoseNoise,
    PushDataset,
    export_hdf5,
    generate,
    generate_skills,
    import_hdf5,
    load_any_dataset,
    load_dataset,
    load_skill_dataset,
    observation_dataset,
    observations_of,
)
from probaff.data.hdf5 import CHUNK_BYTES, read_row
from probaff.data.hdf5_guard import SEAL_MAGIC, USERBLOCK_BYTES
from probaff.data.store import read_manifest
from probaff.errors import DatasetError, InputError
from probaff.features import chapter4_features, chapter5_features, push_interactions
from probaff.models import MixtureOfGPExperts, fit_em
from probaff.sim.registry import kind_of_scene
from probaff.sim.world_files import worlds_dir

FIXTURES = Path(__file__).resolve().parent / "fixtures"

OBSERVED = ("object_ids", "state_before", "state_after", "push_origin", "push_yaw")


@pytest.fixture(scope="module")
def pushes(tmp_path_factory):
    """A noisy push dataset with a wall (schema version 2, walls and ground truth stored)."""
    out = tmp_path_factory.mktemp("h5push") / "ds"
    config = GenerateConfig(
        "near_wall", 10, seed=1, shard_size=4, cloud_points=32, pose_noise=PoseNoise()
    )
    generate(config, out, workers=0, progress=False)
    return out


@pytest.fixture(scope="module")
def picks(tmp_path_factory):
    out = tmp_path_factory.mktemp("h5pick") / "ds"
    generate_skills(GenerateConfig("pick", 4, seed=8, shard_size=3), out, progress=False)
    return out


@pytest.mark.parametrize("which", ["pushes", "picks"])
def test_export_then_import_is_byte_identical(which, request, tmp_path):
    source = request.getfixturevalue(which)
    export_hdf5(source, tmp_path / "ds.h5")
    import_hdf5(tmp_path / "ds.h5", tmp_path / "back")
    assert folder_files(tmp_path / "back") == folder_files(source)  # every shard and the manifest
    a, b = load_any_dataset(source), load_any_dataset(tmp_path / "back")
    assert type(a) is type(b) and set(a.arrays) == set(b.arrays)
    for name, arr in a.arrays.items():
        assert arr.dtype == b[name].dtype and arr.tobytes() == b[name].tobytes(), name
    assert not list(tmp_path.glob(".*tmp*"))


def test_the_layout_is_as_documented(pushes, tmp_path):
    file = export_hdf5(pushes, tmp_path / "ds.h5")
    ds = load_dataset(pushes)
    with h5py.File(file, "r") as fh:
        data = fh["data"]
        attrs = data.attrs
        assert (attrs["format"], attrs["format_version"], attrs["kind"]) == (
            "probaff-hdf5",
            1,
            "push",
        )
        assert attrs["n_rows"] == 10 and json.loads(attrs["object_names"]) == ds.object_names
        manifest = json.loads(attrs["manifest"])
        assert manifest == read_manifest(pushes)
        assert json.loads(attrs["meta"]) == manifest["meta"]
        world = kind_of_scene("near_wall")
        assert attrs["world_yaml"] == (worlds_dir() / "tabletop.yaml").read_text()
        assert attrs["scene_yaml"] == world.scene_path("near_wall").read_text()
        assert set(data) == set(ds.arrays)
        for name, dset in data.items():
            assert dset.attrs["units"] == PushDataset.UNITS[name], name
            assert dset.dtype == ds[name].dtype and dset.shape == ds[name].shape
            if dset.size:
                assert dset.compression == "gzip" and dset.shuffle and dset.fletcher32, name
                assert dset.chunks[1:] == dset.shape[1:]


def test_a_reader_takes_one_push_without_reading_the_file(pushes, tmp_path):
    ds = load_dataset(pushes)
    big = PushDataset(
        {k: np.concatenate([v] * 300) for k, v in ds.arrays.items()}, ds.object_names, ds.meta
    )
    file = export_hdf5(big, tmp_path / "big.h5")
    with h5py.File(file, "r") as fh:
        for name, dset in fh["data"].items():
            if dset.size:  # a chunk is whole rows of at most CHUNK_BYTES (or a single row)
                rows = dset.chunks[0]
                assert rows == 1 or rows * dset[:1].nbytes <= CHUNK_BYTES, name
        row_bytes = big["cloud_points"][:1].nbytes
        assert fh["data/cloud_points"].chunks[0] == CHUNK_BYTES // row_bytes < len(big)
    row = read_row(file, 2345)
    assert set(row) == set(big.arrays)
    for name, value in row.items():
        assert np.array_equal(value, big[name][2345]), name
    with pytest.raises(InputError, match="index must be below the file's 3000 rows"):
        read_row(file, 3000)


def _observed_file(path, ds, names=OBSERVED, clouds=True, units=None, **extra):
    """What another program writes: plain h5py, only observation arrays, no compression."""
    units = {**PushDataset.UNITS, **(units or {})}
    with h5py.File(path, "w") as fh:
        data = fh.create_group("data")
        data.attrs["object_names"] = json.dumps(ds.object_names)
        data.attrs["meta"] = json.dumps(
            {
                k: ds.meta[k]
                for k in ("scene", "push_height", "gripper_opening", "finger_radius", "table_size")
            }
        )
        arrays = {n: ds[n] for n in names}
        arrays["push_distance"] = ds["push_distance"]
        if clouds:
            arrays["cloud_points"] = ds["cloud_points"]
            arrays["cloud_normals"] = ds["cloud_normals"]
        arrays.update(extra)
        for name, arr in arrays.items():
            dset = data.create_dataset(name, data=arr)
            if units.get(name) is not None:
                dset.attrs["units"] = units[name]
    return path


def test_another_programs_file_imports_and_fits(pushes, tmp_path):
    ds = load_dataset(pushes)
    file = _observed_file(tmp_path / "robot.h5", ds)
    out = import_hdf5(file, tmp_path / "robot", shard_size=3)
    robot = load_dataset(out)
    manifest = read_manifest(out)
    assert manifest["schema_version"] == 4 and manifest["plan"]["shard_size"] == 3
    assert robot.observation_only and len(robot) == len(ds)
    assert robot["walls"].shape == (10, 0, 4)  # none logged
    # the observed effect is recomputed from the observed poses, to the bit
    assert np.array_equal(robot["effect"], ds["effect"])
    assert np.array_equal(chapter5_features(robot).values, chapter5_features(ds).values)
    f = chapter4_features(robot)
    model = MixtureOfGPExperts(1, groups=f.groups, gate_features=("f_o",), expert_features=("f_o",))
    with limit_threads(1):
        fit_em(model, f.values, robot["effect"][:, 0], max_iter=2, n_restarts=1, gp_max_iter=10)
        prediction = model.predict(f.values)
    assert prediction.mean.shape == (10, 3) and torch.isfinite(prediction.mean).all()
    # the next import of a file with box footprints instead of clouds samples them
    sizes = np.tile([0.2, 0.15, 0.05], (10, ds.n_objects, 1))
    boxes = _observed_file(tmp_path / "boxes.h5", ds, clouds=False, object_size=sizes)
    sampled = load_dataset(import_hdf5(boxes, tmp_path / "boxes"))
    assert sampled["cloud_points"].shape == (10, ds.n_objects, 256, 3)
    assert np.array_equal(sampled["object_size"], sizes)


def test_another_programs_skill_file_imports(picks, tmp_path):
    ds = load_skill_dataset(picks)
    with h5py.File(tmp_path / "picks.h5", "w") as fh:
        data = fh.create_group("data")
        data.attrs.update(
            {
                "kind": "skill",
                "object_names": json.dumps(ds.object_names),
                "meta": json.dumps(ds.meta),
            }
        )
        for name in SKILL_OBSERVATION_ARRAYS:
            data.create_dataset(name, data=ds[name]).attrs["units"] = ds.UNITS[name]
    robot = load_skill_dataset(import_hdf5(tmp_path / "picks.h5", tmp_path / "robot"))
    assert robot.observation_only and read_manifest(tmp_path / "robot")["schema_version"] == 5
    assert np.array_equal(robot["state_after"], ds["state_after"])


def _edit(path, fn):
    with h5py.File(path, "a") as fh:
        fn(fh)


def _replace(name, value):
    def fn(fh):
        units = fh["data"][name].attrs.get("units")
        del fh["data"][name]
        dset = fh["data"].create_dataset(name, data=value)
        if units is not None:
            dset.attrs["units"] = units

    return fn


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (lambda fh: fh.move("data", "demo"), "has no group '/data'"),
        (
            _replace("state_before", np.zeros((10, 2, 2))),
            r"'state_before' has shape \(10, 2, 2\), expected \(N, K, 3\)",
        ),
        (
            _replace("state_before", np.full((10, 2, 3), b"x")),
            r"'state_before' has dtype \|S1, expected numbers",
        ),
        (
            _replace("object_ids", np.zeros((10, 2))),
            "'object_ids' has dtype float64, expected integers",
        ),
        (
            lambda fh: fh["data/state_before"].__setitem__((2, 0, 1), np.nan),
            r"'state_before' holds NaN or inf in row 2",
        ),
        (
            lambda fh: fh["data/push_yaw"].attrs.__delitem__("units"),
            r"/data/push_yaw has no 'units' attribute; expected 'rad'",
        ),
        (
            lambda fh: fh["data/push_yaw"].attrs.__setitem__("units", "deg"),
            r"'push_yaw' is given in 'deg', but probaff expects 'rad'",
        ),
        (
            lambda fh: fh["data"].attrs.__delitem__("object_names"),
            "lacks the attribute 'object_names'; expected a JSON list",
        ),
        (
            lambda fh: fh["data"].attrs.__setitem__("meta", "{oops"),
            "attribute 'meta' of /data is not JSON",
        ),
        (
            lambda fh: fh["data"].attrs.__setitem__("kind", "grasp"),
            "attribute 'kind' of /data is 'grasp'",
        ),
        (
            lambda fh: fh["data"].create_dataset("speed", data=np.zeros(10)),
            "/data/speed is not a push array",
        ),
        (lambda fh: fh["data"].create_group("extra"), "/data/extra is a group, expected an array"),
        (lambda fh: fh["data/push_distance"].attrs.__setitem__("units", "mm"), "given in 'mm'"),
    ],
)
def test_bad_files_name_the_array_or_attribute_and_write_nothing(pushes, tmp_path, edit, message):
    file = _observed_file(tmp_path / "robot.h5", load_dataset(pushes))
    _edit(file, edit)
    with pytest.raises(DatasetError, match=message):
        import_hdf5(file, tmp_path / "out")
    assert not (tmp_path / "out").exists() and not list(tmp_path.glob(".out*"))


def test_truncated_and_corrupted_files_are_refused(pushes, tmp_path):
    file = export_hdf5(pushes, tmp_path / "ds.h5")
    data = file.read_bytes()
    (tmp_path / "cut.h5").write_bytes(data[: len(data) // 2])
    with pytest.raises(DatasetError, match="do not match the SHA-256 seal probaff wrote"):
        import_hdf5(tmp_path / "cut.h5", tmp_path / "a")
    # without the seal (as another program's file), HDF5's own checks name the damage
    data = bytes(USERBLOCK_BYTES) + data[USERBLOCK_BYTES:]
    (tmp_path / "cut.h5").write_bytes(data[: len(data) // 2])
    with pytest.raises(DatasetError, match="truncated, corrupted or of another format"):
        import_hdf5(tmp_path / "cut.h5", tmp_path / "a")
    (tmp_path / "text.h5").write_text("state_before,state_after\n1,2\n")
    with pytest.raises(DatasetError, match="not a readable HDF5 file"):
        import_hdf5(tmp_path / "text.h5", tmp_path / "a")
    with h5py.File(file, "r") as fh:
        chunk = fh["data/state_before"].id.get_chunk_info(0)
    flipped = bytearray(data)
    for i in range(chunk.byte_offset + 8, chunk.byte_offset + 16):
        flipped[i] ^= 0xFF
    (tmp_path / "flip.h5").write_bytes(bytes(flipped))
    with pytest.raises(
        DatasetError, match=r"/data/state_before cannot be read: the file is truncated or corrupted"
    ):
        import_hdf5(tmp_path / "flip.h5", tmp_path / "a")
    with pytest.raises(DatasetError, match="does not exist"):
        import_hdf5(tmp_path / "none.h5", tmp_path / "a")
    assert not (tmp_path / "a").exists()


def test_import_into_a_folder_holding_a_dataset_loses_nothing(pushes, picks, tmp_path):
    file = export_hdf5(pushes, tmp_path / "ds.h5")
    before = folder_files(picks)
    with pytest.raises(DatasetError, match="already holds a skill dataset; nothing was written"):
        import_hdf5(file, picks)
    assert folder_files(picks) == before
    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "notes.txt").write_text("keep")
    with pytest.raises(DatasetError, match="not empty"):
        import_hdf5(file, tmp_path / "mine")
    assert (tmp_path / "mine" / "notes.txt").read_text() == "keep"
    with pytest.raises(InputError, match=r"out .* is a file"):
        import_hdf5(file, file)
    with pytest.raises(InputError, match=r"file .* is a folder"):
        export_hdf5(pushes, tmp_path)


def test_a_feature_set_asked_of_an_imported_dataset_without_its_arrays(pushes, tmp_path):
    file = _observed_file(tmp_path / "robot.h5", load_dataset(pushes))
    robot = load_dataset(import_hdf5(file, tmp_path / "robot"))
    with pytest.raises(
        InputError,
        match=r"push_interactions .*'ch6.push.hand'.* needs array \['traj_hand'\].*trajector",
    ):
        push_interactions(robot, "hand")
    bare = observation_dataset(observations_of(robot), robot.object_names, {"scene": "near_wall"})
    with pytest.raises(
        InputError,
        match=r"chapter5_features .* needs dataset metadata \['gripper_opening', 'push_height'\]",
    ):
        chapter5_features(bare)


def test_read_row_refuses_rows_that_disagree_and_scalar_arrays(pushes, tmp_path):
    file = _observed_file(tmp_path / "robot.h5", load_dataset(pushes))
    _edit(file, _replace("push_yaw", np.zeros(7)))
    with pytest.raises(
        DatasetError,
        match=r"robot\.h5: the arrays under /data disagree in their number of rows "
        r"\(/data/push_yaw has 7, /data/\w+ has 10\)",
    ):
        read_row(file, 0)
    with pytest.raises(DatasetError, match=r"robot\.h5 \(/data\): array 'push_yaw' has shape"):
        import_hdf5(file, tmp_path / "a")
    scalar = _observed_file(tmp_path / "scalar.h5", load_dataset(pushes))
    _edit(scalar, _replace("push_distance", np.float64(0.1)))
    for read in (lambda: read_row(scalar, 0), lambda: import_hdf5(scalar, tmp_path / "b")):
        with pytest.raises(
            DatasetError, match=r"scalar\.h5: /data/push_distance is a scalar .*dataset"
        ):
            read()
    assert not (tmp_path / "a").exists() and not (tmp_path / "b").exists()


def test_edited_attributes_fail_their_checksum(pushes, tmp_path):
    file = export_hdf5(pushes, tmp_path / "ds.h5")
    with h5py.File(file, "r") as fh:
        meta = json.loads(fh["data"].attrs["meta"])
    _edit(file, lambda fh: fh["data"].attrs.__setitem__("meta", json.dumps({**meta, "seed": 9})))
    sealed = r"ds\.h5 is damaged: its bytes do not match the SHA-256 seal"
    for read in (lambda: import_hdf5(file, tmp_path / "out"), lambda: read_row(file, 0)):
        with pytest.raises(DatasetError, match=sealed):
            read()
    # the seal removed (the user block zeroed): the attributes' own checksum still fails
    data = file.read_bytes()
    file.write_bytes(bytes(USERBLOCK_BYTES) + data[USERBLOCK_BYTES:])
    match = r"ds\.h5: the attributes .*'meta'.* do not match the SHA-256 checksum"
    with pytest.raises(DatasetError, match=match):
        import_hdf5(file, tmp_path / "out")
    with pytest.raises(DatasetError, match=match):
        read_row(file, 0)
    assert not (tmp_path / "out").exists()


def test_a_file_that_crashes_hdf5_is_refused_without_crashing_this_process(tmp_path):
    """Six bytes of the foreign fixture changed: reading every object segfaults HDF5."""
    data = bytearray((FIXTURES / "foreign_big_endian.h5").read_bytes())
    for at, value in {3399: 232, 4519: 236, 4520: 240, 4521: 186, 4522: 218, 6929: 115}.items():
        data[at] = value
    bad = tmp_path / "crash.h5"
    bad.write_bytes(bytes(data))
    for read in (lambda: import_hdf5(bad, tmp_path / "out"), lambda: read_row(bad, 0)):
        with pytest.raises(DatasetError, match=r"crash\.h5 is damaged: reading it crashed HDF5"):
            read()
    assert not (tmp_path / "out").exists()


def test_exported_files_carry_a_seal_other_readers_skip(pushes, tmp_path):
    file = export_hdf5(pushes, tmp_path / "ds.h5")
    head = file.read_bytes()[:USERBLOCK_BYTES]
    digest = hashlib.sha256(file.read_bytes()[USERBLOCK_BYTES:]).hexdigest()
    assert head == SEAL_MAGIC + digest.encode() + b"\n" + bytes(USERBLOCK_BYTES - 85)
    with h5py.File(file, "r") as fh:  # plain h5py reads it: HDF5 skips the user block
        assert fh.userblock_size == USERBLOCK_BYTES
        assert np.array_equal(fh["data/effect"][()], load_dataset(pushes)["effect"])


def _metadata_positions(file, count):
    """`count` byte offsets spread evenly over the bytes of `file` outside its data chunks."""
    chunks = []
    with h5py.File(file, "r") as fh:
        for dset in fh["data"].values():
            if dset.chunks is None:
                continue
            for i in range(dset.id.get_num_chunks()):
                info = dset.id.get_chunk_info(i)
                chunks.append((info.byte_offset, info.byte_offset + info.size))
    size = file.stat().st_size
    inside = np.zeros(size, dtype=bool)
    for start, stop in chunks:
        inside[start:stop] = True
    outside = np.flatnonzero(~inside)
    return outside[np.linspace(0, len(outside) - 1, count).astype(int)].tolist(), size


def test_flipped_bytes_give_an_identical_import_or_one_dataset_error(tmp_path):
    """Every position tried: the same dataset back, or a DatasetError naming the file."""
    source = tmp_path / "ds"
    config = GenerateConfig("near_wall", 4, seed=1, shard_size=4, cloud_points=8)
    generate(config, source, workers=0, progress=False)
    file = export_hdf5(source, tmp_path / "ds.h5")
    first = read_row(file, 1)
    sealed = file.read_bytes()
    metadata, size = _metadata_positions(file, 160)
    positions = sorted(set(metadata) | set(np.linspace(0, size - 1, 80).astype(int).tolist()))
    for pos in positions:  # the seal refuses every flip outside its magic text, before HDF5
        if pos < len(SEAL_MAGIC):
            continue
        flipped = bytearray(sealed)
        flipped[pos] ^= 0xFF
        bad = tmp_path / f"sealed{pos}.h5"
        bad.write_bytes(bytes(flipped))
        with pytest.raises(DatasetError, match=r"is damaged: its bytes do not match the SHA-256"):
            import_hdf5(bad, tmp_path / "never")
    # Without the seal (another program's file), HDF5's own checks: the same dataset back or
    # one DatasetError. Each such file is first read in a separate process, so fewer positions.
    data = bytes(USERBLOCK_BYTES) + sealed[USERBLOCK_BYTES:]
    metadata, size = _metadata_positions(file, 18)
    positions = sorted(set(metadata) | set(np.linspace(0, size - 1, 6).astype(int).tolist()))
    outcomes = {"identical": 0, "refused": 0}
    for i, pos in enumerate(positions):
        flipped = bytearray(data)
        flipped[pos] ^= 0xFF
        bad = tmp_path / "flipped.h5"
        bad.write_bytes(bytes(flipped))
        out = tmp_path / f"out{i}"
        try:
            import_hdf5(bad, out)
        except DatasetError as exc:
            assert "flipped.h5" in str(exc), (pos, str(exc))
            outcomes["refused"] += 1
        else:
            assert folder_files(out) == folder_files(source), pos
            outcomes["identical"] += 1
        try:
            row = read_row(bad, 1)
        except DatasetError as exc:
            assert "flipped.h5" in str(exc), (pos, str(exc))
        else:
            assert row.keys() == first.keys(), pos
            for name, value in first.items():
                assert row[name].tobytes() == value.tobytes(), (pos, name)
    assert outcomes["refused"] >= 3 and outcomes["identical"] >= 3, outcomes
    assert not (tmp_path / "never").exists()
