"""The stepped push rollout: known answers with fixed predictors, and bad input."""

from dataclasses import replace

import numpy as np
import pytest

from probaff.errors import InputError
from probaff.features.chain_geometry import Ch6Geometry
from probaff.models import GPOptions
from probaff.models.transitions.stepped_transition import (
    StepComponents,
    SteppedModelOptions,
    SteppedPushModel,
    SteppedScenes,
    lift,
    rollout,
)

GEO = Ch6Geometry(columns=[0, 1], spacing=0.01)
L = 0.025  # m per step
S = 4  # steps
BOX = 0.1  # m, the boxes' edge


def _fingers():
    finger = np.array([[0.02, 0.02, 0.04]])
    pts, nrm = [], []
    for side in (-0.03, 0.03):
        T = np.eye(4)[None].copy()
        T[0, 1, 3], T[0, 2, 3] = side, 0.02
        p, q = GEO.surface(finger, T)
        pts.append(p[0])
        nrm.append(q[0])
    return np.concatenate(pts), np.concatenate(nrm)


def _scenes(n_objects=2, gap=0.005, yaw=0.3):
    """Boxes in a row ahead of the hand along `yaw`, `gap` apart; the hand commanded S steps."""
    u = np.array([np.cos(yaw), np.sin(yaw)])
    centre = [0.01 + gap + BOX / 2 + k * (BOX + gap) for k in range(n_objects)]
    start = np.array([[*(c * u), yaw] for c in centre])[None]
    commanded = np.array([[*(t * L * u), yaw] for t in range(S + 1)])[None]
    sizes = np.full((1, n_objects, 3), BOX)
    pts, nrm = _fingers()
    return SteppedScenes(sizes, start, commanded, pts, nrm, 0.02)


def _constant(value):
    return lambda X: np.tile(np.asarray(value, float), (len(X), 1))


PUSH = _constant([0.0, L, 0.0])  # every touched box is carried one step along the action


def test_a_hand_on_its_command_carries_the_box_along():
    scenes = _scenes(1)
    out = rollout(StepComponents(PUSH), GEO, scenes)
    np.testing.assert_allclose(out.hand, scenes.commanded, atol=1e-12)
    u = scenes.commanded[0, 1, :2] / L
    np.testing.assert_allclose(out.final[0, 0, :2], scenes.start[0, 0, :2] + S * L * u, atol=1e-9)
    assert out.touched.all() and out.objects.shape == (1, S + 1, 1, 3)


def test_a_zero_backward_model_is_open_loop_chaining():
    scenes = _scenes(2)
    zero = _constant([0.0, 0.0])
    closed = rollout(StepComponents(PUSH, zero, PUSH, zero), GEO, scenes)
    open_loop = rollout(StepComponents(PUSH, None, PUSH, None), GEO, scenes)
    np.testing.assert_array_equal(closed.objects, open_loop.objects)
    np.testing.assert_array_equal(closed.hand, open_loop.hand)
    # o1 carried one step pushes o2 by one step: both move S steps along the push
    u = scenes.commanded[0, 1, :2] / L
    moved = open_loop.final[0, :, :2] - scenes.start[0, :, :2]
    np.testing.assert_allclose(moved, np.tile(S * L * u, (2, 1)), atol=1e-9)


def test_reactions_correct_the_hand_and_the_pushing_object():
    scenes = _scenes(2)
    back = _constant([0.0, -0.004])  # 4 mm short along the action, every step
    out = rollout(StepComponents(PUSH, back, PUSH, back), GEO, scenes)
    u = scenes.commanded[0, 1, :2] / L
    lag = out.hand[0, 1:, :2] - scenes.commanded[0, 1:, :2]
    np.testing.assert_allclose(lag, np.tile(-0.004 * u, (S, 1)), atol=1e-9)
    # o2 holds o1 back by 4 mm per step; o2 itself has no next object to correct it
    moved = out.final[0, :, :2] - scenes.start[0, :, :2]
    np.testing.assert_allclose(moved[0], S * (L - 0.004) * u, atol=1e-9)
    np.testing.assert_allclose(moved[1], S * L * u, atol=1e-9)


def test_a_box_out_of_reach_is_left_alone():
    scenes = _scenes(1, gap=0.5)
    out = rollout(StepComponents(PUSH), GEO, scenes)
    np.testing.assert_array_equal(out.final, scenes.start)
    assert not out.touched.any()


def test_overlapping_objects_are_refused():
    good = _scenes(2)
    start = good.start.copy()
    start[0, 1, :2] = start[0, 0, :2] + 0.05  # o2 half inside o1
    with pytest.raises(InputError, match="scene 0 starts with objects 0 and 1 overlapping"):
        SteppedScenes(
            good.sizes, start, good.commanded, good.finger_points, good.finger_normals, 0.02
        )


def test_predictors_of_the_wrong_shape_are_refused():
    with pytest.raises(InputError, match="hand_forward must return"):
        rollout(StepComponents(_constant([0.0, L])), GEO, _scenes(1))
    with pytest.raises(InputError, match="min_action"):
        rollout(StepComponents(PUSH), GEO, _scenes(1), min_action=0.0)


def test_fitted_components_roll_out(rng):
    X = rng.uniform(size=(30, GEO.n_features))
    options = SteppedModelOptions(gp=replace(SteppedModelOptions().gp, max_iter=2), max_rows=20)
    model = SteppedPushModel(GEO, options, backward=False)
    model.fit_component("hand_forward", X, np.tile([0.0, L, 0.0], (30, 1)))
    assert model.models["hand_forward"].train_X.shape == (20, GEO.n_features)  # the row cap
    out = model.rollout(_scenes(1))
    assert np.isfinite(out.final).all() and out.touched.all()
    with pytest.raises(InputError, match="backward=False"):
        model.components(backward=True)
    with pytest.raises(InputError, match="no hand_backward"):
        model.fit_component("hand_backward", X, X)
    with pytest.raises(InputError, match="kind must be"):
        SteppedModelOptions(kind="forest")
    with pytest.raises(InputError, match="gp must be GPOptions"):
        SteppedModelOptions(gp=2)  # type: ignore[arg-type]
    with pytest.raises(InputError, match="one standard deviation"):
        SteppedModelOptions(gp=GPOptions(noise_floor=[0.1, 0.2]))
    with pytest.raises(TypeError, match="gp_max_iter"):
        SteppedModelOptions(gp_max_iter=2)  # type: ignore[call-arg]


def test_lift_frames_a_planar_pose_at_half_the_height_and_names_bad_input():
    T = lift(np.array([[1.0, 2.0, np.pi / 2]]), 0.4)
    np.testing.assert_allclose(T[0, :3, 3], [1.0, 2.0, 0.2])
    np.testing.assert_allclose(T[0, :2, :2], [[0.0, -1.0], [1.0, 0.0]], atol=1e-12)
    with pytest.raises(InputError, match=r"pose must be \(n, 3\)"):
        lift(np.zeros(3), 0.1)
    with pytest.raises(InputError, match=r"height must be a number or \(2,\) numbers"):
        lift(np.zeros((2, 3)), [0.1, 0.2, 0.3])
    with pytest.raises(InputError, match="pose must be a numeric array"):
        lift("abc", 0.1)
