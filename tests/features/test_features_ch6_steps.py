"""Pushes cut into steps of fixed hand travel, and the stepped model fitted on them."""

import dataclasses

import numpy as np
import pytest

from probaff.data.generation import GenerateConfig, generate
from probaff.errors import InputError
from probaff.features.ch6_push import PLANAR_EFFECT_COLUMNS, push_interactions
from probaff.features.ch6_stepped import fit_stepped, link_training_rows
from probaff.features.ch6_steps import (
    StepOptions,
    check_step_length,
    hand_steps,
    link_steps,
    step_trajectories,
)
from probaff.features.chain_geometry import Ch6Geometry
from probaff.models.transitions.stepped_transition import SteppedModelOptions


@pytest.fixture(scope="module")
def pushes(tmp_path_factory):
    cfg = GenerateConfig("chain_3", 3, seed=4, hand="compliant")
    return generate(cfg, tmp_path_factory.mktemp("steps") / "chain", workers=0, progress=False)


def _straight(ds):
    """The dataset with the hand exactly on a straight commanded path (no reaction)."""
    yaw = ds["push_yaw"]
    u = np.stack([np.cos(yaw), np.sin(yaw)], 1)
    cmd = ds["traj_commanded"].astype(np.float64)
    along = np.einsum("ntj,nj->nt", cmd[..., :2] - ds["push_origin"][:, None], u)
    along = np.clip(np.maximum.accumulate(along, axis=1), 0.0, ds["push_distance"][:, None])
    along[:, -1] = ds["push_distance"]
    path = np.concatenate(
        [ds["push_origin"][:, None] + along[..., None] * u[:, None], cmd[..., 2:]], axis=2
    )
    path = path.astype(np.float32)
    arrays = {**ds.arrays, "traj_commanded": path, "traj_hand": path}
    return dataclasses.replace(ds, arrays=arrays)


def test_steps_of_a_straight_push_sum_to_the_whole_push(pushes):
    ds = _straight(pushes)
    traj = step_trajectories(ds, StepOptions(0.025))
    assert traj.n_steps == 14 and traj.objects.shape == (3, 15, 3, 3)
    steps = hand_steps(traj)
    whole = push_interactions(ds, "hand").effect[:, list(PLANAR_EFFECT_COLUMNS)]
    total = steps.effect.reshape(3, 14, 3).sum(axis=1)
    np.testing.assert_allclose(total, whole, atol=1e-6)
    # a hand on its command has no reaction
    np.testing.assert_allclose(steps.reaction, 0.0, atol=1e-9)


def test_boundaries_are_equal_hand_travel_and_the_recorded_ends(pushes):
    traj = step_trajectories(pushes, StepOptions(0.05))
    u = np.stack([np.cos(traj.push_yaw), np.sin(traj.push_yaw)], 1)
    travel = np.einsum("ntj,nj->nt", traj.commanded[..., :2] - traj.commanded[:, :1, :2], u)
    np.testing.assert_allclose(travel[:, :-1], np.tile(0.05 * np.arange(7), (3, 1)), atol=1e-6)
    np.testing.assert_allclose(traj.objects[:, -1], pushes["state_after"], atol=1e-6)
    np.testing.assert_allclose(traj.objects[:, 0], pushes["state_before"], atol=1e-6)


def test_reaction_is_the_hand_minus_its_command_at_the_step_end(pushes):
    traj = step_trajectories(pushes)
    steps = hand_steps(traj)
    miss = traj.hand[:, 1:, :2] - traj.commanded[:, 1:, :2]
    np.testing.assert_allclose(
        np.linalg.norm(steps.reaction, axis=1), np.linalg.norm(miss, axis=2).ravel(), atol=1e-9
    )
    # a compliant hand pushing three boxes trails its command along the push
    assert np.median(steps.reaction[steps.touches, 1]) < -1e-4
    assert steps.touches.mean() > 0.8 and (steps.actor == -1).all()


def test_object_links_read_the_commanded_motion(pushes):
    traj = step_trajectories(pushes)
    observed = traj.objects[:, 1:, 0]  # o1 commanded to where it went: no reaction
    rows = link_steps(traj, 0, observed)
    np.testing.assert_allclose(rows.reaction, 0.0, atol=1e-9)
    assert (rows.actor == 0).all() and rows.touches.mean() > 0.5
    # rows whose commanded motion is shorter than min_action are dropped
    still = link_steps(traj, 0, traj.objects[:, :-1, 0])
    assert len(still) == 0 and still.features.shape[1] == rows.features.shape[1]
    with pytest.raises(InputError, match="actor must be"):
        link_steps(traj, 2, observed)
    with pytest.raises(InputError, match="commanded must be"):
        link_steps(traj, 0, observed[:, :3])


@pytest.mark.parametrize("bad", [0, -0.025, float("nan"), float("inf"), "2 cm", True])
def test_a_step_length_that_is_not_a_positive_length_is_refused(bad):
    with pytest.raises(InputError, match="step_length must be a positive"):
        StepOptions(bad)


def test_a_step_length_that_does_not_divide_the_push_is_refused(pushes):
    with pytest.raises(InputError, match=r"step_length=0.03 m does not divide the 0.35 m push"):
        step_trajectories(pushes, StepOptions(0.03))
    with pytest.raises(InputError, match=r"0.025 \(14 steps\) or 0.035 \(10 steps\)"):
        check_step_length(0.03, np.array([0.35]))
    assert check_step_length(0.07, np.array([0.35, 0.35])) == 5
    with pytest.raises(InputError, match="share one distance"):
        check_step_length(0.05, np.array([0.35, 0.30]))


def test_a_backward_model_needs_the_commanded_path(pushes):
    drop = ("traj_commanded", "hand_reaction")  # a schema version 2 dataset
    arrays = {k: v for k, v in pushes.arrays.items() if k not in drop}
    old = dataclasses.replace(pushes, arrays=arrays)
    with pytest.raises(InputError, match="traj_commanded"):
        step_trajectories(old)
    # a forward model alone steps the straight commanded push instead
    traj = step_trajectories(old, reaction=False)
    assert traj.n_steps == 14 and np.isfinite(traj.commanded).all()
    no_traj = dataclasses.replace(
        old, arrays={k: v for k, v in old.arrays.items() if not k.startswith("traj_")}
    )
    with pytest.raises(InputError, match="trajectories"):
        step_trajectories(no_traj, reaction=False)


def test_the_stepped_model_fits_and_rolls_out(pushes):
    geo = Ch6Geometry(columns=[0, 1, 2])
    traj = step_trajectories(pushes, StepOptions(0.07), geometry=geo)
    gp = dataclasses.replace(SteppedModelOptions().gp, max_iter=2)
    options = SteppedModelOptions(gp=gp, max_rows=40)
    model = fit_stepped(traj, geo, options)
    assert set(model.models) == {"hand_forward", "hand_backward", "link_forward", "link_backward"}
    links = link_training_rows(model, traj)
    assert set(links.actor) == {0, 1} and links.touches.all()  # both pairs of the row of three
    assert model.models["link_backward"].n_features == geo.n_features + 3
    with_r = model.rollout(traj.scenes())
    without = model.rollout(traj.scenes(), backward=False)
    u = np.stack([np.cos(traj.push_yaw), np.sin(traj.push_yaw)], 1)
    along = np.einsum("nj,nj->n", with_r.final[:, 0, :2] - traj.objects[:, 0, 0, :2], u)
    assert np.isfinite(with_r.final).all() and (along > 0.05).all()
    np.testing.assert_allclose(without.hand, traj.commanded)  # no reaction: on its command
    assert not np.allclose(with_r.hand, traj.commanded)
    forward = fit_stepped(traj, geo, options, backward=False)
    assert set(forward.models) == {"hand_forward", "link_forward"}
    # a model without reactions learns the hand's steps from its commanded poses
    planned = hand_steps(traj, geo, start="commanded")
    np.testing.assert_array_equal(
        forward.models["hand_forward"].train_X.numpy(), planned.features[planned.touches]
    )
    with pytest.raises(InputError, match="unknown start"):
        hand_steps(traj, geo, start="ideal")
