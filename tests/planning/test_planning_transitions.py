"""The transition protocol: quasi-static, simulator and learned models, and its checks."""

import math

import numpy as np
import pytest
import torch
from torch.distributions import Independent, Normal

from probaff.errors import InputError
from probaff.planning.transitions import (
    LearnedTransition,
    PushBatch,
    QuasiStaticTransition,
    SimulatorTransition,
    Transition,
    TransitionPrediction,
    check_transition,
    checked_prediction,
)
from probaff.sim.specs import load_catalogue
from probaff.sim.tabletop_config import load_tabletop

FAR = np.array([-0.4, 0.35, 0.0])  # a battery pose out of the way


def _predict(model, task, book, origins, yaws, battery, **kw):
    """`model`'s prediction of the book and the battery, (N, 2, 3)."""
    poses = np.stack([book, np.broadcast_to(battery, book.shape)], axis=1)
    pushes = PushBatch((task.book, task.battery), poses, origins, yaws, task.push_distance)
    return model.predict(pushes, **kw)


def test_quasi_static_free_push_is_a_translation(task):
    qs = QuasiStaticTransition(task)
    book = np.array([[0.0, 0.0, 0.3]])
    out = _predict(qs, task, book, np.zeros((1, 2)), np.array([0.7]), FAR).mean[0]
    travel = task.push_distance - task.start_gap
    assert np.allclose(out[0, :2], book[0, :2] + travel * np.array([math.cos(0.7), math.sin(0.7)]))
    assert out[0, 2] == pytest.approx(0.3)
    np.testing.assert_array_equal(out[1], FAR)  # the obstacle does not move


def test_quasi_static_battery_stops_the_book_at_contact(task):
    qs = QuasiStaticTransition(task)
    book = np.array([[0.0, 0.0, 0.0]])
    gap = 0.05  # between the book's +x face and the battery's -x face
    battery = np.array([0.12 + gap + 0.13, 0.0, 0.0])
    out = _predict(qs, task, book, np.zeros((1, 2)), np.array([0.0]), battery).mean[0, 0]
    assert not task.collides(out, battery)
    assert out[0] == pytest.approx(gap, abs=qs.step + 1e-9)


def test_quasi_static_rows_with_other_obstacles_are_each_their_own(task):
    qs = QuasiStaticTransition(task)
    book = np.zeros((3, 3))
    batteries = np.array([[0.33, 0.0, 0.0], FAR, [0.36, 0.0, 0.0]])
    poses = np.stack([book, batteries], axis=1)
    objects = (task.book, task.battery)
    yaws = np.zeros(3)
    together = qs.predict(PushBatch(objects, poses, np.zeros((3, 2)), yaws, 0.15)).mean
    for i in range(3):
        one = PushBatch(objects, poses[i : i + 1], np.zeros((1, 2)), yaws[:1], 0.15)
        alone = qs.predict(one).mean
        np.testing.assert_array_equal(together[i], alone[0])
    assert together[0, 0, 0] < together[2, 0, 0] < together[1, 0, 0]


def test_quasi_static_settings_come_from_the_task_or_the_arguments(task):
    assert QuasiStaticTransition(task).start_gap == task.start_gap
    assert QuasiStaticTransition(task).contact_tolerance == task.contact_tolerance
    bare = QuasiStaticTransition(task.world)
    assert bare.start_gap == 0.0 and bare.contact_tolerance == 0.0
    assert QuasiStaticTransition(task.world, start_gap=0.03).start_gap == 0.03
    with pytest.raises(InputError, match=r"QuasiStaticTransition start_gap \(m\) must be"):
        QuasiStaticTransition(task, start_gap=-0.01)


@pytest.mark.parametrize("step", [0, -0.01, float("nan"), float("inf"), "fine"])
def test_quasi_static_step_must_be_positive(task, step):
    with pytest.raises(InputError, match=r"QuasiStaticTransition step \(m\) must be a"):
        QuasiStaticTransition(task, step=step)


def test_quasi_static_free_push_travels_the_full_distance_whatever_the_step(task):
    book = np.array([[0.0, 0.0, 0.0]])
    qs = QuasiStaticTransition(task, step=0.03)
    out = _predict(qs, task, book, np.zeros((1, 2)), np.zeros(1), FAR)
    assert out.mean[0, 0, 0] == pytest.approx(task.push_distance - task.start_gap)


def test_simulated_free_push_agrees_with_the_quasi_static_model(task):
    # an analytic case: a push through the centre of a uniform book translates it
    book = np.array([[0.0, 0.0, 0.0]])
    origins, yaws = task.candidate_pushes(book)
    i = 0  # push along +x
    sim = _predict(SimulatorTransition(task), task, book, origins[:, i], yaws[i : i + 1], FAR)
    qs = _predict(QuasiStaticTransition(task), task, book, origins[:, i], yaws[i : i + 1], FAR)
    s, q = sim.mean[0, 0], qs.mean[0, 0]
    assert np.hypot(*(s[:2] - q[:2])) < 0.02
    assert abs(s[2]) < 0.05 and abs(s[1]) < 0.01
    assert np.hypot(*(sim.mean[0, 1, :2] - FAR[:2])) < 1e-3  # the 15 kg battery stays


class _Effects:
    """A learned model's interface, predicting the same effects for every query."""

    cloud_points = 32
    cloud_noise = 0.0

    def __init__(self, effects):
        self.effects = torch.as_tensor(effects, dtype=torch.float64)

    def predict(self, queries):
        loc = self.effects.expand(len(queries), -1).clone()
        return Independent(Normal(loc, 1e-3 * torch.ones_like(loc), validate_args=False), 1)


def test_a_learned_model_moves_the_objects_it_predicts(task):
    book = np.array([[0.0, 0.0, 0.0], [0.1, 0.1, 1.0]])
    origins, yaws = task.candidate_pushes(book)
    yaw = yaws[[4, 4]]  # push along +y: z_p is world +y, y_p is world -x
    one = LearnedTransition(_Effects([0.0, 0.05, 0.1]), task)
    pred = _predict(one, task, book, origins[:, 4], yaw, FAR)
    np.testing.assert_allclose(pred.mean[:, 0], book + np.array([0.0, 0.05, 0.1]), atol=1e-12)
    np.testing.assert_array_equal(pred.mean[:, 1], np.broadcast_to(FAR, (2, 3)))
    both = LearnedTransition(_Effects([0.0, 0.05, 0.1, 0.01, 0.0, 0.0]), task, seed=3)
    drawn = _predict(both, task, book, origins[:, 4], yaw, FAR, n_samples=5)
    np.testing.assert_allclose(drawn.mean[:, 1], np.broadcast_to(FAR - [0.01, 0, 0], (2, 3)))
    assert drawn.samples is not None and drawn.samples.shape == (5, 2, 2, 3)
    again = LearnedTransition(_Effects([0.0, 0.05, 0.1, 0.01, 0.0, 0.0]), task, seed=3)
    np.testing.assert_array_equal(
        drawn.samples, _predict(again, task, book, origins[:, 4], yaw, FAR, n_samples=5).samples
    )
    assert both.calls == again.calls == 1


@pytest.mark.parametrize("effects", [[0.0, 0.1], [0.0] * 9])
def test_a_learned_model_of_the_wrong_width_is_refused(task, effects):
    book = np.zeros((1, 3))
    with pytest.raises(InputError, match=r"needs \(dy_p, dz_p, dtheta_p\) of its first M <= 2"):
        _predict(
            LearnedTransition(_Effects(effects), task),
            task,
            book,
            np.zeros((1, 2)),
            np.zeros(1),
            FAR,
        )


def test_non_finite_learned_effects_name_the_model(task):
    nan = LearnedTransition(_Effects([float("nan"), 0.0, 0.0]), task)
    with pytest.raises(InputError, match=r"push model _Effects predicted NaN .* not finite"):
        _predict(nan, task, np.zeros((1, 3)), np.zeros((1, 2)), np.zeros(1), FAR)


def test_transitions_refuse_what_they_cannot_use(task):
    world = load_tabletop()
    with pytest.raises(InputError, match="model must be a fitted push model with its features"):
        LearnedTransition("gp", world)  # type: ignore[arg-type]
    with pytest.raises(InputError, match="seed must be an integer >= 0, got -1"):
        LearnedTransition(_Effects([0.0, 0.0, 0.0]), world, seed=-1)
    for kind in (LearnedTransition, SimulatorTransition, QuasiStaticTransition):
        args = (_Effects([0, 0, 0]), "tabletop") if kind is LearnedTransition else ("tabletop",)
        with pytest.raises(InputError, match=rf"{kind.__name__} needs the tabletop world"):
            kind(*args)  # type: ignore[arg-type]
    with pytest.raises(InputError, match="name must be a non-empty label"):
        QuasiStaticTransition(task, name="")
    with pytest.raises(InputError, match=r"transition must be a push transition model.*got str"):
        check_transition("quasi-static")
    for model in (QuasiStaticTransition(task), SimulatorTransition(world)):
        assert isinstance(model, Transition) and check_transition(model) is model


def test_checked_predictions_are_of_the_asked_shapes_and_finite(task):
    qs = QuasiStaticTransition(task)
    good = TransitionPrediction(np.zeros((4, 2, 3)), np.zeros((3, 4, 2, 3)))
    assert checked_prediction(qs, good, (4, 2), 3).mean.shape == (4, 2, 3)
    with pytest.raises(InputError, match="returned ndarray, not a TransitionPrediction"):
        checked_prediction(qs, np.zeros((4, 2, 3)), (4, 2))
    with pytest.raises(InputError, match=r"returned predictive draws of shape \(3, 4, 2, 3\)"):
        checked_prediction(qs, good, (4, 2), 5)
    bad = TransitionPrediction(np.full((4, 2, 3), np.inf))
    with pytest.raises(InputError, match=r"'quasi-static' predicted 24 NaN or infinite value"):
        checked_prediction(qs, bad, (4, 2))


def test_the_simulator_pushes_any_catalogue_objects():
    world, cat = load_tabletop(), load_catalogue()
    objects = (cat["cracker_box"], cat["phone_box"])
    poses = np.array([[[0.0, 0.0, 0.0], [0.3, 0.3, 0.0]]])
    origin = np.array([[-0.15, 0.0]])
    out = (
        SimulatorTransition(world)
        .predict(PushBatch(objects, poses, origin, np.zeros(1), 0.25))
        .mean
    )
    assert out.shape == (1, 2, 3) and out[0, 0, 0] > 0.03
    np.testing.assert_allclose(out[0, 1], poses[0, 1], atol=1e-6)  # untouched


def test_a_push_batch_checks_its_shapes():
    cat = load_catalogue()
    objects = (cat["book"], cat["battery"])
    ok = PushBatch(objects, np.zeros((4, 2, 3)), np.zeros((4, 2)), np.zeros(4), 0.15)
    assert len(ok) == 4 and ok.distance == 0.15
    with pytest.raises(
        InputError, match=r"PushBatch.origins has shape \(3, 2\), expected \(4, 2\)"
    ):
        PushBatch(objects, np.zeros((4, 2, 3)), np.zeros((3, 2)), np.zeros(4), 0.15)
    with pytest.raises(
        InputError, match=r"PushBatch.poses has shape \(1, 3, 3\), expected \(1, 2, 3\)"
    ):
        PushBatch(objects, np.zeros((1, 3, 3)), np.zeros((1, 2)), np.zeros(1), 0.15)
    with pytest.raises(InputError, match=r"PushBatch\.yaws contains 1 NaN"):
        PushBatch(objects, np.zeros((1, 2, 3)), np.zeros((1, 2)), np.array([np.nan]), 0.15)
    with pytest.raises(InputError, match=r"PushBatch\.objects must be the K catalogue objects"):
        PushBatch(("book",), np.zeros((1, 1, 3)), np.zeros((1, 2)), np.zeros(1), 0.15)
    with pytest.raises(InputError, match=r"PushBatch.distance \(m\) must be a finite number > 0"):
        PushBatch(objects, np.zeros((1, 2, 3)), np.zeros((1, 2)), np.zeros(1), 0.0)
