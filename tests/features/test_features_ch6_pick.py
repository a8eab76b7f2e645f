"""Chapter 6 interaction rows of side-view pick datasets."""

import dataclasses

import numpy as np
import pytest

from probaff.data import GenerateConfig, generate_skills
from probaff.errors import InputError
from probaff.features.ch6_pick import SIDEVIEW_EFFECT_COLUMNS, pick_interactions


@pytest.fixture(scope="module")
def picks(tmp_path_factory):
    root = tmp_path_factory.mktemp("c6pick")
    return generate_skills(GenerateConfig("pick", 24, seed=2), root / "pick", progress=False)


def test_pick_rows_see_the_lift(picks):
    rows = pick_interactions(picks)
    assert len(rows) == len(picks) and rows.features.shape == (len(picks), 171)
    assert 0 < rows.lifted.sum() < len(picks)
    lift = float(picks.meta["lift"])
    # along the vertical action, a lifted object rises by the lift, the others stay put
    np.testing.assert_allclose(rows.effect[rows.lifted, 1], lift, atol=0.02)
    assert np.abs(rows.effect[~rows.lifted, 1]).max() < 0.01
    still = [c for c in range(6) if c not in SIDEVIEW_EFFECT_COLUMNS]
    np.testing.assert_allclose(rows.effect[:, still], 0.0, atol=1e-9)
    assert rows.reaction.shape == (len(picks), 2) and np.isfinite(rows.reaction).all()


def test_pick_rows_refuse_other_data(picks, refuses_other_data):
    refuses_other_data(pick_interactions, picks, "place", object())


@pytest.mark.parametrize(
    ("name", "index", "value"),
    [
        ("ee_actual", (3, 1), np.nan),
        ("ee_commanded", (0, 0), np.inf),
        ("state_before", (0, 1), np.nan),
        ("target_xz", (0,), -np.inf),
    ],
)
def test_pick_rows_name_non_finite_values(picks, name, index, value):
    arr = picks[name].copy()
    arr[(2, *index)] = value
    bad = dataclasses.replace(picks, arrays={**picks.arrays, name: arr})
    with pytest.raises(InputError, match=rf"{name} in row 2 .*NaN or infinite"):
        pick_interactions(bad)
