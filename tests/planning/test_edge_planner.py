"""Push-to-edge transitions, A*, the greedy planner and closed-loop episodes."""

import math

import numpy as np
import pytest

from probaff.errors import InputError
from probaff.planning.edge_episode import run_edge_episode
from probaff.planning.edge_planner import plan_astar, plan_greedy
from probaff.planning.edge_task import load_edge_task, sample_episode
from probaff.planning.edge_transitions import (
    EdgeTransition,
    PushReachability,
    QuasiStaticTransition,
    SimulatorTransition,
    TransitionPrediction,
)

FAR = np.array([-0.4, 0.35, 0.0])  # a battery pose out of the way


@pytest.fixture(scope="module")
def task():
    return load_edge_task()


@pytest.fixture(scope="module")
def reach(task):
    return PushReachability(task)


def test_quasi_static_free_push_is_a_translation(task):
    qs = QuasiStaticTransition(task)
    book = np.array([[0.0, 0.0, 0.3]])
    yaw = np.array([0.7])
    out = qs.predict(book, np.zeros((1, 2)), yaw, FAR).mean[0]
    travel = task.push_distance - task.start_gap
    assert np.allclose(out[:2], book[0, :2] + travel * np.array([math.cos(0.7), math.sin(0.7)]))
    assert out[2] == pytest.approx(0.3)


def test_quasi_static_battery_stops_the_book_at_contact(task):
    qs = QuasiStaticTransition(task)
    book = np.array([[0.0, 0.0, 0.0]])
    gap = 0.05  # between the book's +x face and the battery's -x face
    battery = np.array([0.12 + gap + 0.13, 0.0, 0.0])
    out = qs.predict(book, np.zeros((1, 2)), np.array([0.0]), battery).mean[0]
    assert not task.collides(out, battery)
    assert out[0] == pytest.approx(gap, abs=qs.step + 1e-9)


def test_simulated_free_push_agrees_with_the_quasi_static_model(task):
    # an analytic case: a push through the centre of a uniform book translates it
    book = np.array([[0.0, 0.0, 0.0]])
    origins, yaws = task.candidate_pushes(book)
    i = 0  # push along +x
    sim = SimulatorTransition(task).predict(book, origins[:, i], yaws[i : i + 1], FAR).mean[0]
    qs = QuasiStaticTransition(task).predict(book, origins[:, i], yaws[i : i + 1], FAR).mean[0]
    assert np.hypot(*(sim[:2] - qs[:2])) < 0.02
    assert abs(sim[2]) < 0.05 and abs(sim[1]) < 0.01


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

    def __init__(self, inner: EdgeTransition) -> None:
        self.inner, self.name, self.calls, self.sizes = inner, inner.name, 0, []

    def predict(self, book, origins, yaws, battery, n_samples=0):
        self.calls += 1
        self.sizes.append(len(book))
        return self.inner.predict(book, origins, yaws, battery, n_samples)


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
        got = QuasiStaticTransition(task).predict(
            pose[None], origins[:, j], yaws[j : j + 1], s.poses[1]
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

    def predict(self, book, origins, yaws, battery, n_samples=0):
        mean = book.copy()
        mean[:, 0] += 0.05
        samples = None
        if n_samples:
            samples = np.repeat(mean[None], n_samples, axis=0)
            samples[: n_samples // 2, :, 0] = 0.6
        return TransitionPrediction(mean, samples)


def test_risk_aware_planner_prunes_what_the_mean_planner_keeps(task, reach):
    book = np.array([0.0, 0.0, 0.0])
    mean_plan = plan_greedy(task, _Risky(), book, FAR, reach)
    risk_plan = plan_greedy(task, _Risky(), book, FAR, reach, risk=True)
    assert len(mean_plan) == 1 and len(risk_plan) == 0


def test_closed_loop_episode_is_seeded_and_succeeds_with_a_good_model(task, reach):
    a = run_edge_episode(task, QuasiStaticTransition(task), 5, reach=reach, trajectories=False)
    b = run_edge_episode(task, QuasiStaticTransition(task), 5, reach=reach, trajectories=False)
    timeless = [{k: v for k, v in e.to_dict().items() if k != "planning_seconds"} for e in (a, b)]
    assert timeless[0] == timeless[1]
    assert a.success and a.outcome == "success"
    assert task.graspable(np.array(a.final))
    assert a.pushes == len(a.steps) <= task.budget
    for step in a.steps:
        assert step.error == pytest.approx(np.hypot(*(np.subtract(step.after, step.predicted)[:2])))
        assert step.replanned == (step.error > task.replan_distance)


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


@pytest.mark.parametrize("step", [0, -0.01, float("nan"), float("inf"), "fine"])
def test_quasi_static_step_must_be_positive(task, step):
    with pytest.raises(InputError, match=r"QuasiStaticTransition step \(m\) must be a"):
        QuasiStaticTransition(task, step=step)


def test_quasi_static_free_push_travels_the_full_distance_whatever_the_step(task):
    book = np.array([[0.0, 0.0, 0.0]])
    out = QuasiStaticTransition(task, step=0.03).predict(book, np.zeros((1, 2)), np.zeros(1), FAR)
    assert out.mean[0, 0] == pytest.approx(task.push_distance - task.start_gap)


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
    from probaff.planning.edge_task import SearchOptions

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
        QuasiStaticTransition("push_to_edge")  # type: ignore[arg-type]
    with pytest.raises(InputError, match="task must be an EdgeTask"):
        SimulatorTransition(None)  # type: ignore[arg-type]
    with pytest.raises(InputError, match="name must be a non-empty label"):
        QuasiStaticTransition(task, name="")


class _Broken:
    """A model whose predicted means (or only its draws) are NaN."""

    name = "broken"

    def __init__(self, draws_only: bool = False) -> None:
        self.draws_only = draws_only

    def predict(self, book, origins, yaws, battery, n_samples=0):
        mean = book + 0.01
        samples = np.full((n_samples, *book.shape), np.nan) if n_samples else None
        if not self.draws_only:
            mean = np.full_like(book, np.nan)
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

        def predict(self, book, origins, yaws, battery, n_samples=0):
            return TransitionPrediction(book[:1])

    with pytest.raises(InputError, match=r"transition model Short 'short' returned predicted"):
        plan_greedy(task, Short(), np.zeros(3), FAR, reach)
