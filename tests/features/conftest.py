"""Fixtures of the feature tests."""

import dataclasses
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from probaff.data import GenerateConfig, SkillDataset, generate_skills
from probaff.errors import InputError


def _without_trajectories(ds: SkillDataset) -> SkillDataset:
    """`ds` without its ``traj_*``, ``opening_*``, ``ee_commanded`` and ``ee_actual`` arrays."""
    kept = {
        k: v
        for k, v in ds.arrays.items()
        if k not in ("ee_commanded", "ee_actual") and not k.startswith(("opening_", "traj_"))
    }
    return dataclasses.replace(ds, arrays=kept)


@pytest.fixture
def refuses_other_data(tmp_path: Path) -> Callable[..., None]:
    """Check that a skill's interaction rows refuse data they cannot read.

    Returns:
        ``check(interactions, ds, other_scene, bad_geometry)``: `interactions` (the skill's
        rows function) refuses a small dataset of the side-view scene `other_scene` (another
        skill), `ds` stripped of its trajectories, and `ds` with the geometry `bad_geometry`.
    """

    def check(
        interactions: Callable[..., Any], ds: SkillDataset, other_scene: str, bad_geometry: Any
    ) -> None:
        config = GenerateConfig(other_scene, 2, seed=0)
        other = generate_skills(config, tmp_path / "p", progress=False)
        with pytest.raises(InputError, match=f"{ds.skill} dataset"):
            interactions(other)
        with pytest.raises(InputError, match="trajector"):
            interactions(_without_trajectories(ds))
        with pytest.raises(InputError, match="geometry"):
            interactions(ds, geometry=bad_geometry)

    return check
