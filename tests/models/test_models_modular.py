"""Chained predictions of per-skill transition models, against an analytic push rule.

The push model is trained without the simulator: an actor (a 1 cm cylinder standing for the
hand, or a box) moves along +y by d towards a box; the box is pushed through by what is left
of d after the gap, ``max(0, d - gap)``, with ``gap`` the touch distance the chapter 6
features report, and does not move otherwise. The training effects carry 2 mm (0.01 rad) of
measurement noise. A chain of boxes in a row then has a known answer: each box moves by what
is left of the previous box's motion after its gap.

The model sees the continuous feature groups (relative pose and action, 12 columns) and the
geometry's two motion columns. With all 169 columns and a few hundred samples, the binary
shape and contact voxels make box-on-box queries look far from the training data, and the
GP's spread there grows to several cm.
"""

import ast
from pathlib import Path

import numpy as np
import pytest
import torch

import probaff.models.transitions.chain as chain_module
import probaff.models.transitions.modular as modular
from probaff._threads import limit_threads
from probaff.errors import InputError, NotFittedError
from probaff.features import (
    INTERACTION_GROUPS,
    Ch6Geometry,
    box_surface,
    interaction_features,
    tabletop_transform,
)
from probaff.models import (
    ChainPrediction,
    ChainScene,
    InteractionGeometry,
    ModularTransitionModel,
    SkillTransitionModel,
    fit_transition,
)
from probaff.models.transitions.transition_base import sample_effects

N_TRAIN = 160
RADIUS = 0.005  # m, the hand cylinder's radius (1 cm across)
HAND_Z = 0.04  # m, height of the hand's centre above the table
NOISE = 0.002  # m (rad for the yaw), measurement noise of the training effects
CONTINUOUS = [
    *range(INTERACTION_GROUPS["pose"].start, INTERACTION_GROUPS["pose"].stop),
    *range(INTERACTION_GROUPS["action"].start, INTERACTION_GROUPS["action"].stop),
]
GEOMETRY = Ch6Geometry(columns=CONTINUOUS)


def _cylinder(n_around: int = 12, n_up: int = 5, height: float = 0.05):
    """Surface points and outward normals (Q, 3) of the hand: a vertical 1 cm cylinder."""
    ang = np.linspace(0.0, 2 * np.pi, n_around, endpoint=False)
    z = np.linspace(-height / 2, height / 2, n_up)
    a, zz = (v.ravel() for v in np.meshgrid(ang, z))
    normals = np.stack([np.cos(a), np.sin(a), np.zeros_like(a)], axis=1)
    points = RADIUS * normals + np.stack([np.zeros_like(a), np.zeros_like(a), zz], axis=1)
    return points, normals


HAND = _cylinder()


def _at(x, y, z):
    """(N, 4, 4) translations to the (N,) positions x, y, z."""
    x, y, z = np.broadcast_arrays(*(np.atleast_1d(np.asarray(v, float)) for v in (x, y, z)))
    T = np.tile(np.eye(4), (x.size, 1, 1))
    T[:, 0, 3], T[:, 1, 3], T[:, 2, 3] = x, y, z
    return T


def _boxes(sizes, x, y):
    """Upright, unturned boxes resting on the table with their centres at (x, y)."""
    sizes = np.asarray(sizes, float)
    pose = np.column_stack([np.broadcast_to(x, len(sizes)), y, np.zeros(len(sizes))])
    return tabletop_transform(pose, sizes[:, 2])


def _hand_world(T):
    """The hand's points and normals (N, Q, 3) at the (N, 4, 4) poses T."""
    p, n = HAND
    R, t = T[:, :3, :3], T[:, None, :3, 3]
    return p @ R.transpose(0, 2, 1) + t, n @ R.transpose(0, 2, 1)


def _push_samples(rng, n, hand):
    """Features X (n, 14) and noisy effects Y (n, 3) of n pushes by the hand or by boxes."""
    t_size = rng.uniform(0.08, 0.15, (n, 3))
    T_t = _boxes(t_size, 0.0, np.zeros(n))
    t_pts, t_nrm = box_surface(t_size, T_t)
    gap = rng.uniform(0.0, 0.06, n)
    d = rng.uniform(0.002, 0.12, n)
    if hand:
        depth = np.full(n, RADIUS)
        T_s = _at(rng.uniform(-0.3, 0.3, n) * t_size[:, 0], 0.0, HAND_Z)
    else:
        a_size = rng.uniform(0.08, 0.15, (n, 3))
        depth = a_size[:, 1] / 2
        T_s = _boxes(a_size, rng.uniform(-0.3, 0.3, n) * t_size[:, 0], np.zeros(n))
    T_s[:, 1, 3] = -(t_size[:, 1] / 2 + gap + depth)
    if hand:
        a_pts, a_nrm = _hand_world(T_s)
    else:
        a_pts, a_nrm = box_surface(a_size, T_s)
    T_e = T_s.copy()
    T_e[:, 1, 3] += d
    X, _, _ = GEOMETRY.features(t_pts, t_nrm, a_pts, a_nrm, T_s, T_e)
    touch = interaction_features(t_pts, t_nrm, a_pts, a_nrm, T_s, T_e).touch_distance
    along = np.where(np.isfinite(touch), np.maximum(d - touch, 0.0), 0.0)
    Y = np.column_stack([np.zeros(n), along, np.zeros(n)])
    return X, Y + NOISE * rng.standard_normal(Y.shape)


@pytest.fixture(scope="module")
def push_model():
    rng = np.random.default_rng(0)
    parts = [_push_samples(rng, N_TRAIN // 2, hand) for hand in (True, False)]
    X = np.concatenate([p[0] for p in parts])
    Y = np.concatenate([p[1] for p in parts])
    model = SkillTransitionModel("push", backward=False)
    with limit_threads(1):
        fit_transition(model, X, Y)
    return model


@pytest.fixture(scope="module")
def chain(push_model):
    return ModularTransitionModel({"push": push_model}, GEOMETRY)


def _row(sizes, gaps, hand_gap, d, side=None):
    """A row of boxes along +y with surface gaps `gaps`, pushed by the hand along +y by d.

    With `side`, one more box of that size stands 40 cm to the side of the row, last in the
    chain order.
    """
    sizes = np.asarray(sizes, float)
    y = [0.0]
    for k, g in enumerate(gaps):
        y.append(y[-1] + sizes[k, 1] / 2 + g + sizes[k + 1, 1] / 2)
    T = _boxes(sizes, 0.0, np.array(y))
    if side is not None:
        sizes = np.vstack([sizes, side])
        T = np.concatenate([T, _boxes(np.atleast_2d(side), 0.4, np.array([y[-1]]))])
    start = _at(0.0, -(sizes[0, 1] / 2 + hand_gap + RADIUS), HAND_Z)[0]
    end = start.copy()
    end[1, 3] += d
    return ChainScene(sizes, T, HAND[0], HAND[1], start, end)


def _analytic(scene, n_links):
    """Each box's push-through along +y: what is left of its actor's motion after the gap."""
    pts, nrm = box_surface(scene.sizes, scene.T_world_obj)
    hand_p, hand_n = scene.hand_in_world()
    actor = (hand_p[None], hand_n[None], scene.T_world_hand_start[None])
    d = scene.T_world_hand_end[1, 3] - scene.T_world_hand_start[1, 3]
    moves = []
    for k in range(n_links):
        if d < 1e-3:
            moves.append(0.0)
            continue
        T_e = actor[2].copy()
        T_e[:, 1, 3] += d
        touch = interaction_features(
            pts[k : k + 1], nrm[k : k + 1], actor[0], actor[1], actor[2], T_e
        ).touch_distance[0]
        d = max(d - touch, 0.0) if np.isfinite(touch) else 0.0
        moves.append(d)
        actor = (pts[k : k + 1], nrm[k : k + 1], scene.T_world_obj[k : k + 1])
    return np.array(moves)


SIZES = np.array([[0.10, 0.12, 0.10], [0.14, 0.09, 0.12], [0.11, 0.10, 0.09]])
GAPS = (0.04, 0.03)


def test_three_object_chain_matches_analytic_push_through(chain):
    scene = _row(SIZES, GAPS, hand_gap=0.03, d=0.10)
    truth = _analytic(scene, 3)
    assert np.all(truth > 0.01), truth  # every box is pushed through, by different amounts
    pred = chain.predict_chain(scene, n_samples=256, seed=0)
    assert isinstance(pred, ChainPrediction)
    assert pred.samples.shape == (256, 3, 4, 4) and pred.planar.shape == (256, 3, 3)
    assert pred.touched[:, 0].all()
    mean = pred.mean_displacement
    np.testing.assert_allclose(mean[:, 1], truth, atol=0.01)
    np.testing.assert_allclose(mean[:, 0], 0.0, atol=0.01)
    lo, hi = pred.interval(0.9)
    assert np.all(lo[:, 1] <= truth) and np.all(truth <= hi[:, 1]), (lo[:, 1], truth, hi[:, 1])
    assert np.all(pred.std_displacement[:, 1] > 0)
    # the later boxes inherit the spread of the earlier boxes' motions
    assert pred.std_displacement[2, 1] > pred.std_displacement[0, 1]


def test_object_off_to_the_side_is_never_touched(chain):
    scene = _row(SIZES, GAPS, hand_gap=0.03, d=0.10, side=[0.10, 0.10, 0.10])
    pred = chain.predict_chain(scene, n_samples=128, seed=1)
    assert pred.touched[:, :3].any(axis=0).all()
    assert not pred.touched[:, 3].any()
    assert np.array_equal(pred.samples[:, 3], np.broadcast_to(scene.T_world_obj[3], (128, 4, 4)))
    assert np.all(pred.displacement[:, 3] == 0.0)


def test_objects_outside_the_order_stay_put(chain):
    scene = _row(SIZES, GAPS, hand_gap=0.03, d=0.10)
    short = ChainScene(
        scene.sizes,
        scene.T_world_obj,
        scene.hand_points,
        scene.hand_normals,
        scene.T_world_hand_start,
        scene.T_world_hand_end,
        order=(0, 1),
    )
    pred = chain.predict_chain(short, n_samples=64, seed=0)
    assert np.all(pred.displacement[:, 2] == 0.0) and not pred.touched[:, 2].any()
    assert pred.mean_displacement[1, 1] > 0.01


def test_hand_that_misses_moves_nothing(chain):
    scene = _row(SIZES, GAPS, hand_gap=0.03, d=0.10)
    start, end = scene.T_world_hand_start.copy(), scene.T_world_hand_end.copy()
    start[0, 3] = end[0, 3] = 0.3  # beside the row
    miss = ChainScene(scene.sizes, scene.T_world_obj, HAND[0], HAND[1], start, end)
    pred = chain.predict_chain(miss, n_samples=32, seed=0)
    assert not pred.touched.any()
    assert np.all(pred.displacement == 0.0)


def test_seeded_predictions_are_deterministic(chain):
    scene = _row(SIZES, GAPS, hand_gap=0.03, d=0.10)
    a = chain.predict_chain(scene, n_samples=64, seed=7)
    b = chain.predict_chain(scene, n_samples=64, seed=7)
    c = chain.predict_chain(scene, n_samples=64, seed=8)
    assert np.array_equal(a.samples, b.samples) and np.array_equal(a.touched, b.touched)
    assert not np.array_equal(a.samples, c.samples)


def test_final_distribution_is_the_moment_match(chain):
    scene = _row(SIZES, GAPS, hand_gap=0.03, d=0.10)
    pred = chain.predict_chain(scene, n_samples=64, seed=2)
    dist = chain.predict_final_distribution(scene, n_samples=64, seed=2)
    assert isinstance(dist, torch.distributions.MultivariateNormal)
    assert dist.event_shape == (9,)
    flat = pred.planar.reshape(64, 9)
    np.testing.assert_allclose(dist.mean.numpy(), flat.mean(axis=0), atol=1e-12)
    np.testing.assert_allclose(
        dist.covariance_matrix.numpy(), np.cov(flat, rowvar=False) + 1e-10 * np.eye(9), atol=1e-12
    )
    with pytest.raises(InputError, match="n_samples"):
        chain.predict_final_distribution(scene, n_samples=1)


def test_interval_levels(chain):
    pred = chain.predict_chain(_row(SIZES, GAPS, 0.03, 0.10), n_samples=64, seed=0)
    lo50, hi50 = pred.interval(0.5)
    lo90, hi90 = pred.interval(0.9)
    assert np.all(lo90 <= lo50) and np.all(hi50 <= hi90)
    lo, hi = pred.interval(0.9, of="pose")
    np.testing.assert_allclose(lo - pred.start_planar, lo90, atol=1e-12)
    np.testing.assert_allclose(hi - pred.start_planar, hi90, atol=1e-12)
    for bad in (0.0, 1.0, "x"):
        with pytest.raises(InputError, match="level"):
            pred.interval(bad)
    with pytest.raises(InputError, match="of"):
        pred.interval(0.9, of="velocity")


def test_ch6_geometry_motion_columns_and_protocol():
    full = Ch6Geometry(spacing=0.01)
    assert isinstance(full, InteractionGeometry)
    assert full.n_features == 171 and GEOMETRY.n_features == 14
    assert Ch6Geometry().spacing == pytest.approx(0.0125)  # 1.25 r_d
    size = np.array([[0.1, 0.1, 0.1]])
    pts, nrm = full.surface(size, _boxes(size, 0.0, np.zeros(1)))
    T_s = _at(0.0, -0.05 - 0.03 - RADIUS, HAND_Z)  # surfaces 3 cm apart
    T_e = T_s.copy()
    T_e[:, 1, 3] += 0.08
    hp, hn = _hand_world(T_s)
    X, touches, T_a = full.features(pts, nrm, hp, hn, T_s, T_e)
    assert X.shape == (1, 171) and touches.tolist() == [True]
    touch = interaction_features(pts, nrm, hp, hn, T_s, T_e).touch_distance[0]
    # a hand point faces a box point head-on: the touch is r_d = 1 cm before they meet
    assert touch == pytest.approx(0.02, abs=1e-9)
    np.testing.assert_allclose(X[0, -2:], [0.08, 0.08 - touch])
    np.testing.assert_allclose(T_a[0, :3, 1], [0.0, 1.0, 0.0], atol=1e-12)
    X14, _, _ = GEOMETRY.features(pts, nrm, hp, hn, T_s, T_e)
    np.testing.assert_array_equal(X14[0], np.r_[X[0, CONTINUOUS], X[0, -2:]])
    X2, _, _ = Ch6Geometry(columns=[]).features(pts, nrm, hp, hn, T_s, T_e)
    np.testing.assert_array_equal(X2, X[:, -2:])
    for bad in ({"columns": [169]}, {"columns": [1, 1]}, {"columns": [], "motion": False}):
        with pytest.raises(InputError, match="columns"):
            Ch6Geometry(**bad)


def test_separating_axis_overlap_rule():
    size = np.full((2, 3), 0.1)
    turned = tabletop_transform(np.array([[0.0, 0.0, 0.0], [0.1, 0.1, np.pi / 4]]), size[:, 2])
    # B's diagonal separates the boxes although neither of A's axes does
    ChainScene(size, turned, HAND[0], HAND[1], *_hand_path())
    turned[1, :2, 3] = 0.08
    with pytest.raises(InputError, match=r"overlap.*T_world_obj"):
        ChainScene(size, turned, HAND[0], HAND[1], *_hand_path())
    touching = _boxes(size, 0.0, np.array([0.0, 0.1]))  # faces in contact
    ChainScene(size, touching, HAND[0], HAND[1], *_hand_path())
    stacked = _boxes(size, 0.0, np.array([0.0, 0.05]))
    stacked[1, 2, 3] += 0.11  # above the other box, not inside it
    ChainScene(size, stacked, HAND[0], HAND[1], *_hand_path())


def _hand_path(d=0.1):
    start = _at(0.0, -0.2, HAND_Z)[0]
    end = start.copy()
    end[1, 3] += d
    return start, end


def test_bad_input_names_the_argument(chain, push_model):
    scene = _row(SIZES, GAPS, hand_gap=0.03, d=0.10)
    with pytest.raises(InputError, match="n_samples"):
        chain.predict_chain(scene, n_samples=1.5)
    with pytest.raises(InputError, match="seed"):
        chain.predict_chain(scene, seed=-1)
    with pytest.raises(InputError, match="one skill used for another"):
        ModularTransitionModel({"pick": push_model}, GEOMETRY)
    with pytest.raises(InputError, match="unknown skill key"):
        ModularTransitionModel({"shove": push_model}, GEOMETRY)
    with pytest.raises(InputError, match="geometry"):
        ModularTransitionModel({"push": push_model}, object())
    with pytest.raises(InputError, match="effect_columns"):
        ModularTransitionModel({"push": push_model}, GEOMETRY, effect_columns=(0, 6))
    with pytest.raises(InputError, match="effect components"):
        ModularTransitionModel({"push": push_model}, GEOMETRY, effect_columns=(1,)).predict_chain(
            scene
        )
    args = [scene.sizes, scene.T_world_obj, HAND[0], HAND[1], *_hand_path()]
    nan_pose = scene.T_world_obj.copy()
    nan_pose[1, 0, 3] = np.nan
    with pytest.raises(InputError, match="T_world_obj"):
        ChainScene(args[0], nan_pose, *args[2:])
    with pytest.raises(InputError, match="sizes"):
        ChainScene(-args[0], *args[1:])
    with pytest.raises(InputError, match="hand_normals"):
        ChainScene(*args[:3], 2 * HAND[1], *args[4:])
    with pytest.raises(InputError, match="T_world_hand_end"):
        ChainScene(*args[:5], args[4])
    with pytest.raises(InputError, match="skill"):
        ChainScene(*args, skill="throw")
    for order in ((0, 0), (3,), (0.5,)):
        with pytest.raises(InputError, match="order"):
            ChainScene(*args, order=order)
    with pytest.raises(InputError, match="ChainScene"):
        chain.predict_chain("scene")


def test_missing_or_unfitted_models():
    scene = _row(SIZES, GAPS, hand_gap=0.03, d=0.10)
    unfitted = ModularTransitionModel({"push": SkillTransitionModel("push")}, GEOMETRY)
    with pytest.raises(NotFittedError):
        unfitted.predict_chain(scene)
    pick_only = ModularTransitionModel({"pick": SkillTransitionModel("pick")}, GEOMETRY)
    with pytest.raises(InputError, match="no 'push' model"):
        pick_only.predict_chain(scene)


@pytest.mark.parametrize("module", [modular, chain_module])
def test_models_layer_does_not_import_the_feature_layer(module):
    tree = ast.parse(Path(module.__file__).read_text())
    imported = {n.module for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)}
    imported |= {a.name for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names}
    assert not {
        m
        for m in imported
        if m and m.startswith(("probaff.features", "probaff.sim", "probaff.data"))
    }


class _SpyGeometry(Ch6Geometry):
    """Records the length of every action that reaches the feature code."""

    def __init__(self) -> None:
        super().__init__(columns=CONTINUOUS)
        self.lengths: list[np.ndarray] = []

    def features(self, *args):
        T_s, T_e = args[4], args[5]
        self.lengths.append(np.linalg.norm(T_e[:, :3, 3] - T_s[:, :3, 3], axis=1))
        return super().features(*args)


def test_actions_that_do_not_move_never_reach_the_features(push_model):
    scene = _row(SIZES, GAPS, hand_gap=0.03, d=0.10, side=[0.10, 0.10, 0.10])
    detour = ChainScene(
        scene.sizes,
        scene.T_world_obj,
        HAND[0],
        HAND[1],
        scene.T_world_hand_start,
        scene.T_world_hand_end,
        order=(0, 3, 1, 2),  # the box to the side is never touched, so 1 and 2 stay put
    )
    spy = _SpyGeometry()
    pred = ModularTransitionModel({"push": push_model}, spy).predict_chain(detour, n_samples=32)
    assert [len(x) for x in spy.lengths] == [1, 32]  # the hand's link, then 0 -> 3 only
    assert min(x.min() for x in spy.lengths) >= 1e-3
    assert pred.touched[:, 0].all() and not pred.touched[:, 1:].any()
    assert np.all(pred.displacement[:, 1:] == 0.0)


def test_mixture_predictions_are_sampled_per_expert():
    loc = torch.tensor([[[0.0, 0.0], [10.0, 20.0]]], dtype=torch.float64)  # (N=1, M=2, E=2)
    scale = torch.full_like(loc, 1e-3)
    probs = torch.tensor([[0.25, 0.75]], dtype=torch.float64)
    dist = torch.distributions.MixtureSameFamily(
        torch.distributions.Categorical(probs=probs),
        torch.distributions.Independent(torch.distributions.Normal(loc, scale), 1),
    )
    draws = sample_effects(dist, 4000, torch.Generator().manual_seed(0))
    assert draws.shape == (4000, 1, 2)
    second = draws[:, 0, 0] > 5.0
    assert abs(second.double().mean().item() - 0.75) < 0.03
    np.testing.assert_allclose(draws[second, 0].mean(0).numpy(), [10.0, 20.0], atol=1e-3)
    np.testing.assert_allclose(draws[~second, 0].mean(0).numpy(), [0.0, 0.0], atol=1e-3)
    with pytest.raises(InputError, match="independent normals"):
        sample_effects(torch.distributions.Normal(loc, scale), 1, torch.Generator())
