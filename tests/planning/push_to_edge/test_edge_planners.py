"""Push-to-edge planning: the book-and-battery adapter, reachability, A* and the greedy planner."""

import math

import numpy as np
import pytest

from probaff.errors import InputError
from probaff.planning.push_to_edge.episode import run_edge_episode
from probaff.planning.push_to_edge.planners import (
    PushReachability,
    plan_astar,
    plan_greedy,
    predict_books,
)
from probaff.planning.push_to_edge.task import SearchOptions, sample_episode
from probaff.planning.transitions import (
    PushBatch,
    QuasiStaticTransition,
    SimulatorTransition,
    Transition,
    TransitionPrediction,
)

FAR = np.array([-0.4, 0.35, 0.0])  # a battery pose out of the way


def test_reachability_is_exact_for_snapped_pushes_and_order_free(task, reach):
    import torch

    rng = np.random.default_rng(0)
    origins = rng.uniform([-0.3, -0.35], [0.5, 0.35], (40, 2))
    yaws = rng.uniform(-math.pi, math.pi, 40)
    fresh = PushReachability(task)
    backwards = fresh(origins[::-1], yaws[::-1])[::-1]
    forwards = reach(origins, yaws)
    assert np.array_equal(forwards, backwards)
    o, y = reach.snap(origins, yaws)
    ik = reach.arm.solve_pushes(torch.as_tensor(o), torch.as_tensor(y), task.push_distance)
    assert np.array_equal(ik.ok.numpy(), forwards)
    assert 0 < forwards.sum() < len(forwards)


class _Counting:
    """Wraps a transition and counts its calls and their batch sizes."""

    def __init__(self, inner: Transition) -> None:
        self.inner, self.name, self.calls, self.sizes = inner, inner.name, 0, []

    def predict(self, pushes, *, n_samples=0, rng=None):
        self.calls += 1
        self.sizes.append(len(pushes))
        return self.inner.predict(pushes, n_samples=n_samples)


def test_astar_reaches_the_goal_with_one_prediction_per_batch(task, reach):
    s = sample_episode(task, np.random.default_rng(1))
    model = _Counting(QuasiStaticTransition(task))
    plan = plan_astar(task, model, s.poses[0], s.poses[1], reach)
    assert plan.reaches_goal
    assert task.graspable(plan.predicted[-1])
    assert len(plan) >= task.heuristic(s.poses[0])
    assert plan.predictions == model.calls
    assert math.ceil(plan.expansions / task.search.batch) <= model.calls <= plan.expansions
    assert max(model.sizes) > task.directions  # candidates of several nodes in one call
    # the plan replays: each push from the previous predicted pose gives the next one
    pose = s.poses[0]
    for yaw, want in zip(plan.yaws, plan.predicted, strict=True):
        origins, yaws = task.candidate_pushes(pose[None])
        j = int(np.argmin(np.abs(np.angle(np.exp(1j * (yaws - yaw))))))
        got = predict_books(
            task,
            QuasiStaticTransition(task),
            pose[None],
            origins[:, j],
            yaws[j : j + 1],
            s.poses[1],
        )
        assert np.allclose(got.mean[0], want)
        pose = want


def test_greedy_takes_the_push_that_gains_most(task, reach):
    s = sample_episode(task, np.random.default_rng(2))
    plan = plan_greedy(task, QuasiStaticTransition(task), s.poses[0], s.poses[1], reach)
    assert len(plan) == 1
    assert task.progress(plan.predicted[0]) < task.progress(s.poses[0])


class _Risky:
    """Means that stay on the table, half of whose draws fall off the +x edge."""

    name = "risky"

    def predict(self, pushes, *, n_samples=0, rng=None):
        mean = pushes.poses.copy()
        mean[:, 0, 0] += 0.05
        samples = None
        if n_samples:
            samples = np.repeat(mean[None], n_samples, axis=0)
            samples[: n_samples // 2, :, 0, 0] = 0.6
        return TransitionPrediction(mean, samples)


def test_risk_aware_planner_prunes_what_the_mean_planner_keeps(task, reach):
    book = np.array([0.0, 0.0, 0.0])
    mean_plan = plan_greedy(task, _Risky(), book, FAR, reach)
    risk_plan = plan_greedy(task, _Risky(), book, FAR, reach, risk=True)
    assert len(mean_plan) == 1 and len(risk_plan) == 0


def test_bad_planner_input(task, reach):
    qs = QuasiStaticTransition(task)
    with pytest.raises(InputError, match=r"budget .* must be a positive integer, got 0"):
        plan_astar(task, qs, np.zeros(3), FAR, reach, budget=0)
    with pytest.raises(InputError, match="book contains 1 NaN"):
        plan_astar(task, qs, np.array([0.0, np.nan, 0.0]), FAR, reach)
    with pytest.raises(InputError, match="unknown search"):
        run_edge_episode(task, qs, 0, search="dfs")
    with pytest.raises(InputError, match="overlaps the battery"):
        plan_astar(task, qs, np.array([0.1, 0.0, 0.0]), np.array([0.2, 0.05, 0.3]), reach)
    with pytest.raises(InputError, match="task must be an EdgeTask"):
        plan_greedy("push_to_edge", qs, np.zeros(3), FAR, reach)  # type: ignore[arg-type]


def test_a_start_off_the_table_is_refused_not_planned(task, reach):
    qs = QuasiStaticTransition(task)
    fallen = np.array([0.42, 0.50, 0.0])  # graspable by its overhang, but off the +y side
    for planner in (plan_astar, plan_greedy):
        with pytest.raises(InputError, match=r"start pose of the book, \[0.42, 0.5, 0.0\], is off"):
            planner(task, qs, fallen, FAR, reach)
    with pytest.raises(InputError, match=r"start pose of the battery, .* is off the"):
        plan_astar(task, qs, np.zeros(3), np.array([0.0, 0.5, 0.0]), reach)


@pytest.mark.parametrize(
    ("kw", "match"),
    [
        ({"xy_resolution": 0}, r"xy_resolution \(m\) must be a finite number > 0, got 0"),
        ({"xy_resolution": -0.01}, r"xy_resolution \(m\) must be a finite number > 0"),
        ({"yaw_bins": 0}, "yaw_bins must be a positive integer, got 0"),
        ({"yaw_bins": 2.5}, "yaw_bins must be a positive integer, got 2.5"),
    ],
)
def test_reachability_grid_must_be_positive(task, kw, match):
    with pytest.raises(InputError, match=match):
        PushReachability(task, **kw)


def test_search_resolutions_must_be_positive(task):
    for name in ("xy_resolution", "yaw_resolution", "step_bound"):
        with pytest.raises(InputError, match=rf"search.{name} must be a finite number > 0"):
            SearchOptions(**{name: 0.0})


def test_planners_refuse_what_is_not_a_model(task, reach):
    qs = QuasiStaticTransition(task)
    book = np.zeros(3)
    for planner in (plan_astar, plan_greedy):
        with pytest.raises(
            InputError, match=r"transition must be a push transition model.*got str"
        ):
            planner(task, "quasi-static", book, FAR, reach)  # type: ignore[arg-type]
        with pytest.raises(InputError, match="reach must be the arm's PushReachability"):
            planner(task, qs, book, FAR, None)  # type: ignore[arg-type]
    with pytest.raises(InputError, match=r"transition must be a push transition model.*got str"):
        run_edge_episode(task, "quasi-static", 0, reach=reach)  # type: ignore[arg-type]
    with pytest.raises(InputError, match="simulator must be a PushSimulator"):
        run_edge_episode(task, qs, 0, simulator="pymunk", reach=reach)  # type: ignore[arg-type]
    with pytest.raises(InputError, match="unknown search"):
        run_edge_episode(task, qs, 0, search=["astar"])  # type: ignore[arg-type]
    with pytest.raises(InputError, match="task must be an EdgeTask"):
        PushReachability("push_to_edge")  # type: ignore[arg-type]


class _Broken:
    """A model whose predicted means (or only its draws) are NaN."""

    name = "broken"

    def __init__(self, draws_only: bool = False) -> None:
        self.draws_only = draws_only

    def predict(self, pushes, *, n_samples=0, rng=None):
        mean = pushes.poses + 0.01
        samples = np.full((n_samples, *mean.shape), np.nan) if n_samples else None
        if not self.draws_only:
            mean = np.full_like(mean, np.nan)
        return TransitionPrediction(mean, samples)


def test_non_finite_predictions_are_an_error_not_a_dead_end(task, reach):
    book = np.zeros(3)
    match = r"transition model _Broken 'broken' predicted \d+ NaN .* predictions are not finite"
    for planner in (plan_astar, plan_greedy):
        with pytest.raises(InputError, match=match):
            planner(task, _Broken(), book, FAR, reach)
    with pytest.raises(InputError, match=match + ".*refit the model"):
        run_edge_episode(task, _Broken(), 0, reach=reach, trajectories=False)
    with pytest.raises(InputError, match=r"predicted .* NaN or infinite value.* predictive draws"):
        plan_greedy(task, _Broken(draws_only=True), book, FAR, reach, risk=True)


def test_a_prediction_of_the_wrong_shape_is_refused(task, reach):
    class Short:
        name = "short"

        def predict(self, pushes, *, n_samples=0, rng=None):
            return TransitionPrediction(pushes.poses[:1])

    with pytest.raises(
        InputError,
        match=r"transition model Short 'short' returned predicted poses of shape \(1, 2, 3\)",
    ):
        plan_greedy(task, Short(), np.zeros(3), FAR, reach)


def test_the_adapter_moves_the_book_and_leaves_the_battery_out(task):
    book = np.array([[0.0, 0.0, 0.3], [0.1, -0.1, 0.0]])
    origins, yaws = task.candidate_pushes(book)
    counting = _Counting(SimulatorTransition(task))
    pred = predict_books(task, counting, book, origins[:, 2], yaws[[2, 2]], FAR)
    assert pred.mean.shape == (2, 3) and pred.samples is None
    assert counting.sizes == [2]
    poses = np.stack([book, np.broadcast_to(FAR, (2, 3))], axis=1)
    pushes = PushBatch((task.book, task.battery), poses, origins[:, 2], yaws[[2, 2]], 0.15)
    full = SimulatorTransition(task).predict(pushes)
    np.testing.assert_array_equal(pred.mean, full.mean[:, 0])
    risky = predict_books(task, _Risky(), book, origins[:, 0], yaws[[0, 0]], FAR, n_samples=4)
    assert risky.samples is not None and risky.samples.shape == (4, 2, 3)
    assert (risky.samples[:2, :, 0] == 0.6).all()
