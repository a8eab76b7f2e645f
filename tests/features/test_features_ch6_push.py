"""Chapter 6 interaction rows of tabletop push datasets."""

import dataclasses

import numpy as np
import pytest

from probaff.data.generation import GenerateConfig, generate
from probaff.errors import InputError
from probaff.features.ch6_push import PLANAR_EFFECT_COLUMNS, push_interactions


@pytest.fixture(scope="module")
def chain(tmp_path_factory):
    cfg = GenerateConfig("chain_3", 12, seed=1)
    return generate(cfg, tmp_path_factory.mktemp("c6") / "chain", workers=0, progress=False)


def test_hand_rows_follow_the_push(chain):
    rows = push_interactions(chain, "hand")
    assert len(rows) == len(chain) and rows.features.shape == (len(chain), 171)
    assert rows.touches.all() and (rows.actor == -1).all()
    # o1's displacement, turned into the push frame, is the effect's (dx, dy)
    yaw = chain["push_yaw"]
    move = chain["state_after"][:, 0, :2] - chain["state_before"][:, 0, :2]
    along = move[:, 0] * np.cos(yaw) + move[:, 1] * np.sin(yaw)
    np.testing.assert_allclose(rows.effect[:, 1], along, atol=1e-9)
    turn = chain["state_after"][:, 0, 2] - chain["state_before"][:, 0, 2]
    np.testing.assert_allclose(rows.effect[:, 5], turn, atol=1e-9)
    still = [c for c in range(6) if c not in PLANAR_EFFECT_COLUMNS]
    np.testing.assert_allclose(rows.effect[:, still], 0.0, atol=1e-9)
    # the hand tracks its path closely: its end-point deviation is a few millimetres at most
    assert rows.reaction.shape == (len(chain), 2)
    assert np.abs(rows.reaction).max() < 0.01


def test_object_rows_chain_consecutive_pairs(chain):
    rows = push_interactions(chain, "objects")
    assert set(rows.target - rows.actor) == {1}
    assert np.all(rows.reaction == 0.0)
    # in a row of three the pushed objects touch the next ones, which move along the push
    assert rows.touches.mean() > 0.8
    assert np.median(rows.effect[rows.touches, 1]) > 0.02


def test_bad_inputs_are_refused(chain):
    with pytest.raises(InputError, match="kind"):
        push_interactions(chain, "feet")
    with pytest.raises(InputError, match="geometry"):
        push_interactions(chain, geometry="ch6")
    circle = chain.object_names.index("nut_container")
    ids = chain["object_ids"].copy()
    ids[:, 1] = circle
    round_one = dataclasses.replace(chain, arrays={**chain.arrays, "object_ids": ids})
    with pytest.raises(InputError, match="cuboid"):
        push_interactions(round_one, "objects")
    no_traj = dataclasses.replace(
        chain,
        arrays={k: v for k, v in chain.arrays.items() if not k.startswith("traj_")},
    )
    with pytest.raises(InputError, match="trajector"):
        push_interactions(no_traj, "hand")


@pytest.mark.parametrize(
    ("kind", "name", "index", "value"),
    [
        ("hand", "traj_hand", (5, 0), np.nan),
        ("hand", "push_yaw", (), np.inf),
        ("hand", "push_origin", (1,), np.nan),
        ("objects", "state_before", (1, 2), np.nan),
        ("objects", "state_after", (2, 0), -np.inf),
    ],
)
def test_non_finite_values_are_named(chain, kind, name, index, value):
    arr = chain[name].copy()
    arr[(4, *index)] = value
    bad = dataclasses.replace(chain, arrays={**chain.arrays, name: arr})
    with pytest.raises(InputError, match=rf"{name} in row 4 .*NaN or infinite"):
        push_interactions(bad, kind)
