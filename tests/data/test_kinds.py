"""The registry of dataset kinds: the built-ins, a kind registered with a class of its own.

Each kind registers itself in the module that generates it; a module added to `probaff.data`
(here, to a folder on its path) is found by the registry's next lookup.
"""

import sys
from dataclasses import replace
from typing import ClassVar

import numpy as np
import pytest

from probaff.data import (
    ArrayDataset,
    DatasetKind,
    GenerateConfig,
    PushDataset,
    SkillDataset,
    dataset_kind,
    dataset_kinds,
    generate,
    load_any_dataset,
    readable_versions,
    register_dataset_kind,
    scene_kind,
)
from probaff.data.config import base_plan
from probaff.data.kinds import DEFAULT_KIND, unregister_dataset_kind
from probaff.errors import DatasetError, InputError
from probaff.sim import WorldKind, register_world, world_kind
from probaff.sim.registry import unregister_world


class DotDataset(ArrayDataset):
    KIND = "dots"
    REQUIRED: ClassVar[dict[str, str]] = {"object_ids": "int16", "x": "float64"}

    @property
    def rows_label(self) -> str:
        return "dots"

    def check_plan(self, plan):
        return None if plan["trajectories"] else "hold no trajectories"


def dot_shard(config, rows, seeds):
    x = np.random.default_rng(seeds).standard_normal(rows)
    return {"object_ids": np.zeros((rows, 1), dtype=np.int16), "x": x}


def dot_manifest(config):
    return {"schema_version": 7, "object_names": ["dot"], "meta": {"scene": config.scene}}


DOTS = DatasetKind(
    name="dots",
    world_kind="dots",
    dataset_type=DotDataset,
    schema_versions=(7,),
    make_shard=dot_shard,
    manifest=dot_manifest,
    plan=lambda config: {**base_plan(config), "mean": 0.0},
    summarize=lambda ds: {"mean_x": float(ds["x"].mean())},
    unit="dot",
)


@pytest.fixture
def dots(tmp_path):
    (tmp_path / "dot_cloud.yaml").write_text("description: normal dots\n")
    register_world(
        WorldKind(
            name="dots",
            label="dot",
            load_world=dict,
            simulate=np.random.standard_normal,
            scenes=tmp_path,
            load_scene=str,
            dataset_kind="dots",
            describe_scene=lambda name: "normal dots",
        )
    )
    register_dataset_kind(DOTS)
    yield DOTS
    unregister_dataset_kind("dots")
    unregister_world("dots")


def test_the_built_in_kinds():
    assert [k.name for k in dataset_kinds()][:2] == ["push", "skill"]
    assert dataset_kind("push").dataset_type is PushDataset and DEFAULT_KIND == "push"
    assert dataset_kind("skill").dataset_type is SkillDataset
    assert readable_versions()["push"] == (1, 2, 6) and readable_versions()["skill"] == (3,)
    assert [dataset_kind(n).make_shard.__module__ for n in ("push", "skill")] == [
        "probaff.data.push_generation",
        "probaff.data.skill_generation",
    ]  # each kind registers itself in its own module


NEW_KIND_MODULE = """
from typing import ClassVar

from probaff.data.dataset import ArrayDataset
from probaff.data.kinds import DatasetKind, register_dataset_kind


class NewDotDataset(ArrayDataset):
    KIND = "dots"
    REQUIRED: ClassVar[dict[str, str]] = {"object_ids": "int16", "x": "float64"}


register_dataset_kind(
    DatasetKind(
        name="dots",
        world_kind="dots",
        dataset_type=NewDotDataset,
        schema_versions=(7,),
        make_shard=lambda config, rows, seeds: {},
        manifest=lambda config: {},
        order=-1,
    )
)
"""


def test_a_kind_in_a_new_module_of_the_package_is_found(tmp_path, monkeypatch):
    import probaff.data

    (tmp_path / "zz_dots_generation.py").write_text(NEW_KIND_MODULE)
    monkeypatch.setattr(probaff.data, "__path__", [*probaff.data.__path__, str(tmp_path)])
    register_world(replace(world_kind("office"), name="dots", dataset_kind="dots"))
    try:
        assert dataset_kind("dots").order == -1  # found, named nowhere else
        assert [k.name for k in dataset_kinds()][:3] == ["dots", "push", "skill"]
    finally:
        unregister_dataset_kind("dots")
        unregister_world("dots")
        sys.modules.pop("probaff.data.zz_dots_generation", None)


def test_a_kind_with_its_own_dataset_class(dots, tmp_path):
    ds = generate(GenerateConfig("dot_cloud", n=5, seed=1, shard_size=3), tmp_path / "a")
    assert isinstance(ds, DotDataset) and len(ds) == 5 and ds.meta["mean"] == 0.0
    assert readable_versions()["dots"] == (7,)
    assert dots.summarize(load_any_dataset(tmp_path / "a"))["mean_x"] == float(ds["x"].mean())
    with pytest.raises(DatasetError, match="hold no trajectories"):
        generate(GenerateConfig("dot_cloud", n=2, trajectories=False), tmp_path / "b")


def test_bad_and_clashing_kinds_are_refused(dots):
    with pytest.raises(InputError, match="registered already"):
        register_dataset_kind(DOTS)
    with pytest.raises(InputError, match="makes 'push' datasets, not 'dots2'"):
        register_dataset_kind(replace(DOTS, name="dots2", world_kind="tabletop"))
    with pytest.raises(InputError, match="unknown world kind"):
        register_dataset_kind(replace(DOTS, name="dots3", world_kind="moon"))
    with pytest.raises(InputError, match="not registered"):
        unregister_dataset_kind("dots4")
    with pytest.raises(InputError, match="unknown dataset kind 'moon'"):
        dataset_kind("moon")
    with pytest.raises(InputError, match="subclass of"):
        replace(DOTS, dataset_type=dict)
    with pytest.raises(InputError, match="schema_versions"):
        replace(DOTS, schema_versions=())
    with pytest.raises(InputError, match="make_shard of 'dots' must be callable"):
        replace(DOTS, make_shard=None)
    with pytest.raises(InputError, match="unit must be a non-empty string"):
        replace(DOTS, unit="")


def test_a_scene_that_makes_no_dataset_is_refused(tmp_path):
    (tmp_path / "still.yaml").write_text("description: nothing moves\n")
    register_world(replace(world_kind("office"), name="still", scenes=tmp_path, load_scene=str))
    try:
        with pytest.raises(InputError, match="'still' is a office scene, which makes no dataset"):
            scene_kind("still")
    finally:
        unregister_world("still")
