"""Chapter 6 interaction rows of side-view place datasets.

Also covers the shared geometry of the rows, probaff.features.chain_geometry (Ch6Geometry).
"""

import dataclasses

import numpy as np
import pytest

from probaff.data import GenerateConfig, generate_skills
from probaff.errors import InputError
from probaff.features import (
    SIDEVIEW_EFFECT_COLUMNS,
    TABLE_SLAB_THICKNESS,
    Ch6Geometry,
    apply_effect,
    place_interactions,
    sideview_transform,
)
from probaff.sim.sideview_config import load_sideview

R_D = Ch6Geometry().config.contact_distance


@pytest.fixture(scope="module")
def places(tmp_path_factory):
    root = tmp_path_factory.mktemp("c6place")
    return generate_skills(GenerateConfig("place", 24, seed=2), root / "place", progress=False)


@pytest.fixture(scope="module")
def rows(places):
    return place_interactions(places)


def _held(ds, name):
    """(N, 3) the held cube's side-view pose in state array `name`."""
    return ds[name][np.arange(len(ds)), ds["target"].astype(int)]


def _with(ds, name, row, index, value):
    """A copy of `ds` whose array `name` holds `value` at ``[row, *index]``."""
    arr = ds[name].copy()
    arr[(row, *index)] = value
    return dataclasses.replace(ds, arrays={**ds.arrays, name: arr})


def test_place_rows_see_the_release(places, rows):
    n = len(places)
    assert len(rows) == n and rows.features.shape == (n, 171)
    assert rows.T_world_action.shape == (n, 4, 4) and rows.reaction.shape == (n, 2)
    np.testing.assert_array_equal(rows.placed, places["placed"])
    assert 0 < rows.placed.sum() < n
    release = places["release_height"]
    # the action goes down, so a placed cube's drop by the release height is +y
    np.testing.assert_allclose(rows.effect[rows.placed, 1], release[rows.placed], atol=0.01)
    np.testing.assert_allclose(rows.effect[rows.placed, 2:4], 0.0, atol=0.02)
    # a cube that falls off drops further than the release height, or tips over the edge
    fell = ~rows.placed
    further = rows.effect[fell, 1] - release[fell] > 0.02
    tipped = np.abs(rows.effect[fell, 3]) > 0.2
    assert np.all(further | tipped)
    drop = np.linalg.norm(rows.effect[:, 1:3], axis=1)
    assert drop[fell].mean() > drop[rows.placed].mean() + 0.05
    still = [c for c in range(6) if c not in SIDEVIEW_EFFECT_COLUMNS]
    np.testing.assert_allclose(rows.effect[:, still], 0.0, atol=1e-9)
    # the tcp holds its commanded end point within a few millimetres
    assert np.isfinite(rows.reaction).all() and np.abs(rows.reaction).max() < 0.005
    # only a release closer than r_d to the support top touches it
    assert rows.touches.any()
    assert np.all(release[rows.touches] < R_D + 1e-3)


def test_action_frame_and_round_trip(places, rows):
    start = _held(places, "state_before")
    T_a = rows.T_world_action
    np.testing.assert_allclose(T_a[:, [0, 2], 3], start[:, :2], atol=1e-9)
    # y down and z along world x, up to the tolerance of the arm's IK
    n = len(places)
    np.testing.assert_allclose(T_a[:, :3, 1], np.tile([0.0, 0.0, -1.0], (n, 1)), atol=5e-3)
    np.testing.assert_allclose(T_a[:, :3, 2], np.tile([1.0, 0.0, 0.0], (n, 1)), atol=5e-3)
    # the release pose from the route: the cube's bottom `release_height` above the target top
    height = places["size"][np.arange(len(places)), places["target"].astype(int), 2]
    release = start.copy()
    release[:, 1] = places["target_xz"][:, 1] + places["release_height"] + 0.5 * height
    T_after = apply_effect(T_a, sideview_transform(release), rows.effect)
    np.testing.assert_allclose(T_after, sideview_transform(_held(places, "state_after")), atol=2e-3)
    # exactly, from the commanded lowering
    rows_, end = np.arange(len(places)), places["traj_length"].astype(int) - 1
    cmd = places["ee_commanded"].astype(np.float64)
    T_release = sideview_transform(start)
    T_release[:, [0, 2], 3] += cmd[rows_, end, :2] - cmd[:, 0, :2]
    T_after = apply_effect(T_a, T_release, rows.effect)
    np.testing.assert_allclose(T_after, sideview_transform(_held(places, "state_after")), atol=1e-9)


def test_support_is_the_object_or_the_table_slab(places, rows):
    support = places["support"].astype(int)
    table = support < 0
    assert table.any() and (~table).any()
    cube = _held(places, "state_before")
    slot = np.where(table, 0, support)
    below = places["state_before"][np.arange(len(places)), slot]
    # the slab's centre lies half its thickness below the table top, at x = 0
    below[table] = (0.0, -0.5 * TABLE_SLAB_THICKNESS, 0.0)
    # the cube's start in B_t (A_t's axes: x the viewing axis, y down, z world x)
    want = np.column_stack(
        [np.zeros(len(places)), below[:, 1] - cube[:, 1], cube[:, 0] - below[:, 0]]
    )
    np.testing.assert_allclose(rows.features[:, 125:128], want, atol=1e-3)
    # a cube put on the table always lands there
    assert rows.placed[table].all()


def test_custom_geometry_and_world(places, rows):
    geo = Ch6Geometry(columns=list(range(125, 131)) + list(range(163, 169)))
    world = load_sideview()
    short = place_interactions(places, geometry=geo, world=world)
    assert short.features.shape == (len(places), 14)
    np.testing.assert_allclose(short.features[:, :6], rows.features[:, 125:131])
    # the action's length is the commanded lowering: the hold height less the release height
    lowering = world.place.hold_height - places["release_height"]
    np.testing.assert_allclose(short.features[:, 7], lowering, atol=2e-3)


def test_place_rows_refuse_other_data(places, refuses_other_data):
    refuses_other_data(place_interactions, places, "pick", "ch6")
    empty = dataclasses.replace(places, arrays={k: v[:0] for k, v in places.arrays.items()})
    with pytest.raises(InputError, match="no places"):
        place_interactions(empty)


@pytest.mark.parametrize(
    ("name", "index", "value"),
    [
        ("ee_actual", (5, 0), np.nan),
        ("ee_commanded", (0, 1), np.inf),
        ("state_after", (-1, 1), np.nan),
        ("state_before", (0, 2), -np.inf),
        ("size", (0, 0), np.nan),
    ],
)
def test_non_finite_values_are_named(places, name, index, value):
    bad = _with(places, name, 3, index, value)
    with pytest.raises(InputError, match=rf"{name} in row 3 .*NaN or infinite"):
        place_interactions(bad)


def test_samples_after_the_skill_are_not_read(places, rows):
    length = places["traj_length"].astype(int)
    i = int(np.argmin(length))
    assert length[i] < places["traj_time"].shape[1]
    bad = _with(places, "ee_actual", i, (length[i], 0), np.nan)
    np.testing.assert_array_equal(place_interactions(bad).effect, rows.effect)
