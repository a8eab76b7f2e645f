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


def test_path_reaction_of_a_compliant_hand(tmp_path):
    # a compliant hand pushing a row of three lags its command along the push
    cfg = GenerateConfig("chain_3", 6, seed=2, hand="compliant")
    ds = generate(cfg, tmp_path / "soft", workers=0, progress=False)
    end = push_interactions(ds, "hand")
    rows = push_interactions(ds, "hand", reaction="path")
    r = ds["hand_reaction"].shape[1]
    assert rows.reaction.shape == (len(ds), 4) and rows.reaction_path.shape == (len(ds), r, 2)
    np.testing.assert_allclose(rows.reaction[:, :2], end.reaction)  # the end point first
    np.testing.assert_allclose(rows.reaction[:, 2:], rows.reaction_path.mean(axis=1))
    # along the action (y) the hand trails its command while it pushes three objects
    assert (rows.reaction_path[:, 1:-1, 1].mean(axis=1) < -1e-3).all()
    # the action frame's y is the pushing frame's z_p: the along components agree
    np.testing.assert_allclose(rows.reaction_path[..., 1], ds["hand_reaction"][..., 1], atol=1e-9)
    objects = push_interactions(ds, "objects", reaction="path")
    assert objects.reaction.shape == (len(objects), 4) and not objects.reaction.any()
    with pytest.raises(InputError, match="unknown reaction"):
        push_interactions(ds, "hand", reaction="middle")


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
