"""Files written by earlier releases and by other programs, committed under fixtures/.

The push datasets were written by probaff's own code at the last commit of schema versions 1
and 2, and the HDF5 files by plain h5py with dtypes probaff does not write itself (see
fixtures/README.md). Today's readers are checked against the bytes on disk, read with numpy
and h5py alone, not against a dataset today's code wrote.

Covers probaff.data.store (old schema versions), probaff.data.hdf5 and
probaff.data.observations (other programs' dtypes and a file of no rows).
"""

import json
import shutil
from pathlib import Path

import h5py
import numpy as np
import pytest
from data_helpers import folder_files

from probaff.data import export_hdf5, import_hdf5, load_dataset, summarize
from probaff.data.schema import REQUIRED_ARRAYS, PushDataset
from probaff.data.store import read_manifest
from probaff.errors import DatasetError, InputError
from probaff.features import chapter4_features, chapter5_features, push_interactions
from probaff.sim.geometry import push_frame_effect

FIXTURES = Path(__file__).resolve().parent / "fixtures"
TRUE = ("true_state_before", "true_state_after", "true_effect")


def _shard_arrays(root: Path) -> dict[str, np.ndarray]:
    """The arrays of a dataset folder, read with numpy alone: its shards in order, joined."""
    shards = [np.load(p) for p in sorted((root / "shards").glob("*.npz"))]
    return {k: np.concatenate([s[k] for s in shards]) for k in shards[0].files}


@pytest.mark.parametrize("version", [1, 2])
def test_a_dataset_written_by_an_earlier_release_loads_bit_identically(version, tmp_path):
    source = FIXTURES / f"push_v{version}"
    folder = tmp_path / "old"
    shutil.copytree(source, folder)
    before = folder_files(folder)
    manifest = json.loads((source / "manifest.json").read_text())
    assert manifest["schema_version"] == version and manifest["plan"]["n"] == 3
    ds = load_dataset(folder)
    assert folder_files(folder) == before  # reading leaves the old files as they were
    assert read_manifest(folder) == manifest
    on_disk = _shard_arrays(source)
    assert set(ds.arrays) == set(on_disk)
    for name, arr in on_disk.items():
        assert ds[name].dtype == arr.dtype and ds[name].shape == arr.shape, name
        assert ds[name].tobytes() == arr.tobytes(), name
    assert set(REQUIRED_ARRAYS) <= set(ds.arrays)
    assert len(ds) == 3 and not ds.observation_only and not ds.has_reaction
    assert ds.simulated_version == version
    assert ds.object_names == manifest["object_names"]
    assert manifest["meta"].items() <= ds.meta.items()  # with the plan's entries beside it
    # version 2 alone stores the exact poses beside the measured ones
    assert (set(TRUE) <= set(ds.arrays)) == (version == 2)
    exact = on_disk["true_effect"] if version == 2 else on_disk["effect"]
    assert np.array_equal(ds.true_effect, exact)
    # the stored effect is the pushing-frame difference of the stored poses (m, m, rad)
    for i in range(len(ds)):
        k = int(np.flatnonzero(on_disk["object_ids"][i] >= 0)[0])
        want = push_frame_effect(
            on_disk["state_before"][i, k : k + 1],
            on_disk["state_after"][i, k : k + 1],
            float(on_disk["push_yaw"][i]),
        )[0]
        np.testing.assert_allclose(on_disk["effect"][i, k], want, atol=1e-12)


@pytest.mark.parametrize("version", [1, 2])
def test_features_and_round_trips_of_an_old_dataset(version, tmp_path):
    ds = load_dataset(FIXTURES / f"push_v{version}")
    assert np.isfinite(chapter4_features(ds).values).all()
    assert np.isfinite(chapter5_features(ds).values).all()
    end = push_interactions(ds, "hand", reaction="end")
    assert np.isfinite(end.reaction).all()
    with pytest.raises(InputError, match="regenerate"):  # the path needs version 6 arrays
        push_interactions(ds, "hand", reaction="path")
    summary = summarize(ds)
    assert summary["n_pushes"] == 3 and (summary["pose_noise"] is None) == (version == 1)
    # exported and imported, the old dataset comes back array for array, bit for bit
    back = load_dataset(
        import_hdf5(
            export_hdf5(FIXTURES / f"push_v{version}", tmp_path / "x.h5"), tmp_path / "back"
        )
    )
    assert read_manifest(tmp_path / "back")["schema_version"] == version
    for name, arr in ds.arrays.items():
        assert back[name].tobytes() == arr.tobytes(), name


def _h5(name: str) -> dict[str, np.ndarray]:
    """The arrays of a fixture HDF5 file as stored, read with h5py alone."""
    with h5py.File(FIXTURES / name, "r") as fh:
        return {k: np.asarray(v[()]) for k, v in fh["data"].items()}


@pytest.mark.parametrize("name", ["foreign_float32.h5", "foreign_big_endian.h5"])
def test_another_programs_dtypes_import_with_their_values(name, tmp_path):
    stored = _h5(name)
    assert stored["state_before"].dtype.str == ("<f4" if "float32" in name else ">f8")
    ds = load_dataset(import_hdf5(FIXTURES / name, tmp_path / "ds"))
    assert isinstance(ds, PushDataset) and ds.observation_only and len(ds) == 3
    assert ds.object_names == ["box_a", "box_b"]
    for key, arr in stored.items():
        # converted to the schema's native dtype; a float32 value widens exactly
        dtype = {**PushDataset.REQUIRED, **PushDataset.OPTIONAL}[key]
        assert ds[key].dtype == np.dtype(dtype) and ds[key].dtype.isnative, key
        assert np.array_equal(ds[key], arr.astype(ds[key].dtype)), key
    # the values themselves, not only their conversion: 0.1 as float32 is not 0.1
    want = 0.1 if "big_endian" in name else float(np.float32(0.1))
    assert ds["state_before"][0, 0, 0] == want
    assert ds["push_distance"].tolist() == [want, 0.125, want]
    # the effect is computed from the stored poses (pushing frame: along, across, turn)
    np.testing.assert_allclose(ds["effect"][0, 0], [0.0, 0.05, 0.0625], atol=1e-7)
    np.testing.assert_allclose(ds["effect"][0, 1], 0.0, atol=0)
    assert np.isfinite(chapter4_features(ds).values).all()


def test_a_file_of_no_rows_is_refused_by_name_and_writes_nothing(tmp_path):
    assert _h5("foreign_zero_rows.h5")["state_before"].shape == (0, 2, 3)
    out = tmp_path / "ds"
    with pytest.raises(
        DatasetError,
        match=r"foreign_zero_rows\.h5 \(/data\): push observations hold no rows: 'object_ids' "
        r"has 0 rows; a dataset needs at least one push",
    ):
        import_hdf5(FIXTURES / "foreign_zero_rows.h5", out)
    assert not out.exists() or not any(out.iterdir())
