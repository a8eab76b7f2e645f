"""Each feature set states what it reads and names what a dataset lacks.

Covers probaff.features.requirements and the ``REQUIRES`` of each feature module.
"""

import dataclasses

import numpy as np
import pytest

from probaff.data import GenerateConfig, PushDataset, SkillDataset, generate_skills, make_shard
from probaff.data.queries import world_meta
from probaff.errors import InputError
from probaff.features import (
    FEATURE_REQUIREMENTS,
    Requirements,
    cells,
    ch4,
    ch5,
    ch6_pick,
    ch6_place,
    ch6_push,
    ch6_scenes,
    chapter4_features,
    chapter5_features,
    pick_interactions,
    place_interactions,
    push_interactions,
    push_scenes,
    requirements,
)
from probaff.sim.specs import load_catalogue
from probaff.sim.tabletop_config import load_tabletop

PUSH_SETS = {
    "ch4": chapter4_features,
    "ch5": chapter5_features,
    "ch6.push.hand": lambda ds: push_interactions(ds, "hand"),
    "ch6.push.objects": lambda ds: push_interactions(ds, "objects"),
    "ch6.scenes": push_scenes,
}


@pytest.fixture(scope="module")
def chain():
    config = GenerateConfig("chain_3", 4, seed=2, shard_size=4, cloud_points=16)
    return PushDataset(make_shard(config, 0), sorted(load_catalogue()), world_meta(load_tabletop()))


@pytest.fixture(scope="module")
def skills(tmp_path_factory):
    root = tmp_path_factory.mktemp("req")
    return {
        skill: generate_skills(GenerateConfig(skill, 3, seed=1), root / skill, progress=False)
        for skill in ("pick", "place")
    }


def test_every_feature_set_states_what_it_reads():
    assert set(FEATURE_REQUIREMENTS) == {
        "ch3.cells",
        "ch4",
        "ch5",
        "ch6.push.hand",
        "ch6.push.objects",
        "ch6.scenes",
        "ch6.pick",
        "ch6.place",
    }
    push = {**PushDataset.REQUIRED, **PushDataset.OPTIONAL}
    skill = {**SkillDataset.REQUIRED, **SkillDataset.OPTIONAL}
    for name, req in FEATURE_REQUIREMENTS.items():
        known = skill if name in ("ch6.pick", "ch6.place") else push
        assert set(req.arrays) <= set(known), name
        assert not set(req.arrays) & {"mass", "ground_friction", "contact_friction", "friction"}
    assert ch4.REQUIRES is requirements("ch4") and ch5.REQUIRES is requirements("ch5")
    assert {
        "hand": requirements("ch6.push.hand"),
        "objects": requirements("ch6.push.objects"),
    } == ch6_push.REQUIRES
    assert ch6_scenes.REQUIRES.name == "ch6.scenes"
    assert (ch6_pick.REQUIRES.name, ch6_place.REQUIRES.name) == ("ch6.pick", "ch6.place")
    assert cells.REQUIRES.arrays == () and cells.REQUIRES.meta == ()
    with pytest.raises(InputError, match=r"unknown feature set 'ch9'; the feature sets are"):
        requirements("ch9")
    with pytest.raises(InputError, match=r"Requirements.arrays must be a tuple of names"):
        Requirements("x", "f", ["a"])  # type: ignore[arg-type]
    with pytest.raises(InputError, match=r"Requirements.function must be a non-empty string"):
        Requirements("x", "")


@pytest.mark.parametrize("name", sorted(PUSH_SETS))
def test_a_push_dataset_lacking_an_array_or_entry_is_named(chain, name):
    req = FEATURE_REQUIREMENTS[name]
    PUSH_SETS[name](chain)  # the full dataset has all it needs
    optional = [a for a in req.arrays if a not in PushDataset.REQUIRED]
    for array in optional:
        lacking = dataclasses.replace(
            chain, arrays={k: v for k, v in chain.arrays.items() if not k.startswith("traj_")}
        )
        with pytest.raises(InputError, match=rf"feature set '{name}'.*needs array \['{array}'\]"):
            PUSH_SETS[name](lacking)
    for entry in req.meta:
        meta = {k: v for k, v in chain.meta.items() if k != entry}
        with pytest.raises(InputError, match=rf"needs dataset metadata \['{entry}'\]"):
            PUSH_SETS[name](dataclasses.replace(chain, meta=meta))
    # an object with arrays and meta, such as planner queries, is checked alike
    stub = type("Stub", (), {"arrays": {}, "meta": dict(chain.meta)})()
    arrays, meta = req.missing(stub)
    assert arrays == list(req.arrays) and meta == []


@pytest.mark.parametrize(
    ("skill", "function", "flag"),
    [("pick", pick_interactions, "lifted"), ("place", place_interactions, "placed")],
)
def test_a_skill_dataset_lacking_an_array_is_named(skills, skill, function, flag):
    ds = skills[skill]
    assert len(function(ds).features) == 3
    lacking = dataclasses.replace(ds, arrays={k: v for k, v in ds.arrays.items() if k != flag})
    with pytest.raises(InputError, match=rf"needs array \['{flag}'\], which this skill dataset"):
        function(lacking)
    trajectory = {"traj_time", "traj_length", "ee_commanded", "ee_actual", "traj_objects"}
    bare = dataclasses.replace(
        ds,
        arrays={
            k: v
            for k, v in ds.arrays.items()
            if k not in trajectory and not k.startswith("opening_")
        },
    )
    with pytest.raises(
        InputError, match=r"\['traj_length', 'ee_commanded', 'ee_actual'\].*trajector"
    ):
        function(bare)
    if skill == "pick":
        meta = {k: v for k, v in ds.meta.items() if k != "lift"}
        with pytest.raises(InputError, match=r"needs dataset metadata \['lift'\]"):
            function(dataclasses.replace(ds, meta=meta))
    assert np.isfinite(function(ds).effect).all()
