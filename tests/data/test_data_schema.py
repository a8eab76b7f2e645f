"""Push schema version 6: the hand's reaction along the path, and older versions still read."""

from dataclasses import replace

import numpy as np
import pytest

from probaff.data import GenerateConfig, generate
from probaff.data.schema import (
    REACTION_ARRAYS,
    READABLE_SCHEMA_VERSIONS,
    SCHEMA_VERSION,
    PushDataset,
    schema_version_for,
)
from probaff.data.store import load_dataset, read_manifest, save_dataset
from probaff.errors import DatasetError, InputError
from probaff.features.ch6_push import push_interactions
from probaff.sim.geometry import push_frame_effect

CONFIG = GenerateConfig(scene="modular_push", n=6, seed=3, shard_size=3, hand="compliant")


@pytest.fixture(scope="module")
def compliant(generated):
    return generated(CONFIG, "compliant")


def test_a_new_dataset_records_the_reaction_along_the_path(compliant):
    manifest = read_manifest(compliant)
    assert manifest["schema_version"] == SCHEMA_VERSION == 6
    assert manifest["plan"]["hand_mode"] == "compliant"
    ds = load_dataset(compliant)
    hand = ds.meta["hand"]
    assert hand["mode"] == "compliant" and hand["stiffness_n_per_m"] > 0
    r = ds["hand_reaction"]
    assert r.shape == (6, hand["reaction_samples"], 3) and r.dtype == np.float64
    assert ds["traj_commanded"].shape == ds["traj_hand"].shape
    np.testing.assert_allclose(r[:, 0], 0.0, atol=1e-9)  # the hand starts on its command
    # the last sample is the end of the recorded path: actual minus commanded, pushing frame
    for i in range(len(ds)):
        end = push_frame_effect(
            ds["traj_commanded"][i, -1:].astype(float),
            ds["traj_hand"][i, -1:].astype(float),
            float(ds["push_yaw"][i]),
        )[0]
        np.testing.assert_allclose(r[i, -1], end, atol=2e-6)
    # the commanded path runs straight along z_p over the push distance
    start = ds["traj_commanded"][:, 0, :2]
    np.testing.assert_allclose(start, ds["push_origin"], atol=1e-3)
    travel = np.linalg.norm(ds["traj_commanded"][:, -1, :2] - start, axis=1)
    np.testing.assert_allclose(travel, ds["push_distance"], atol=2e-3)


def test_the_hand_mode_is_part_of_the_plan(compliant, tmp_path):
    import shutil

    out = tmp_path / "ds"
    shutil.copytree(compliant, out)
    with pytest.raises(DatasetError):
        generate(replace(CONFIG, hand="stiff"), out, workers=0, resume=True, progress=False)


def test_versions_1_and_2_are_still_read(compliant, tmp_path):
    """Today's dataset less its version 6 arrays, saved as version 1; datasets that earlier
    releases wrote are committed fixtures, checked in tests/data/test_old_files.py."""
    ds = load_dataset(compliant)
    old = PushDataset(
        {k: v for k, v in ds.arrays.items() if k not in REACTION_ARRAYS},
        list(ds.object_names),
        {k: v for k, v in ds.meta.items() if k != "hand"},
    )
    assert old.simulated_version == 1 and not old.has_reaction
    save_dataset(old, tmp_path / "v1")
    assert read_manifest(tmp_path / "v1")["schema_version"] == 1
    back = load_dataset(tmp_path / "v1")
    assert set(READABLE_SCHEMA_VERSIONS) == {1, 2, 6}
    # the end-point reaction reads as before; the path needs the version 6 arrays
    end = push_interactions(back, "hand", reaction="end")
    np.testing.assert_allclose(end.reaction, push_interactions(ds, "hand").reaction)
    with pytest.raises(InputError, match="regenerate"):
        push_interactions(back, "hand", reaction="path")
    assert schema_version_for(True) == 2 and schema_version_for(False, reaction=True) == 6


def test_a_newer_version_is_refused_by_name(compliant, tmp_path, copy_dataset):
    out = copy_dataset(compliant, tmp_path / "v7", schema_version=SCHEMA_VERSION + 1)
    with pytest.raises(DatasetError, match="schema version 7"):
        load_dataset(out)


def test_hand_settings_of_generation_are_checked():
    with pytest.raises(InputError, match="hand must be None"):
        replace(CONFIG, hand="springy").validate()
    with pytest.raises(InputError, match="hand must be None"):
        replace(CONFIG, hand=1).validate()
    assert replace(CONFIG, hand=None).validate().hand is None
