"""One closed-loop push-to-edge episode: seeded, replanning, its record, bad arguments."""

import json

import numpy as np
import pytest

from probaff.errors import InputError
from probaff.planning.push_to_edge.episode import EDGE_SEARCHES, run_edge_episode
from probaff.planning.push_to_edge.planners import push_admissible
from probaff.planning.transitions import QuasiStaticTransition, TransitionPrediction


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


def test_the_greedy_episode_records_every_plan_and_step(task, reach):
    qs = QuasiStaticTransition(task)
    episode = run_edge_episode(task, qs, 1, search="greedy", reach=reach, label="g")
    record = json.loads(json.dumps(episode.to_dict()))
    assert record["planner"] == "g" and set(EDGE_SEARCHES) == {"astar", "greedy"}
    assert len(record["plans"]) == record["replans"] + 1 == len(record["planning_seconds"])
    assert all(len(p) <= 1 for p in record["plans"])  # greedy plans one push at a time
    for step in episode.steps:
        assert len(step.hand) > 1 and len(step.book_path) > 1
        np.testing.assert_allclose(step.book_path[-1], step.after, atol=1e-9)


def test_episode_arguments_are_checked(task, reach):
    qs = QuasiStaticTransition(task)
    with pytest.raises(InputError, match="unknown search"):
        run_edge_episode(task, qs, 0, search="dfs")
    with pytest.raises(InputError, match="seed must be an integer >= 0, got -1"):
        run_edge_episode(task, qs, -1, reach=reach)
    with pytest.raises(InputError, match="task must be an EdgeTask"):
        run_edge_episode("push_to_edge", qs, 0, reach=reach)  # type: ignore[arg-type]
    with pytest.raises(InputError, match="reach must be the arm's PushReachability"):
        run_edge_episode(task, qs, 0, reach="ik")  # type: ignore[arg-type]


class _Short:
    """The quasi-static model with every predicted move cut to `scale` of its length."""

    name = "short"

    def __init__(self, task, scale: float) -> None:
        self.inner, self.scale = QuasiStaticTransition(task), scale

    def predict(self, pushes, *, n_samples=0, rng=None):
        pred = self.inner.predict(pushes, n_samples=n_samples, rng=rng)
        short = pushes.poses + self.scale * (pred.mean - pushes.poses)
        samples = None if pred.samples is None else np.broadcast_to(short, pred.samples.shape)
        return TransitionPrediction(short, samples)


def test_a_push_is_admitted_by_the_planner_s_own_test(task):
    battery = np.array([-0.3, -0.3, 0.0])
    qs = QuasiStaticTransition(task)
    for risk in (False, True):
        inside = push_admissible(
            task, qs, np.array([0.0, 0.1, 0.0]), battery, np.array([-0.2, 0.1]), 0.0, risk=risk
        )
        over = push_admissible(
            task, qs, np.array([0.45, 0.1, 0.0]), battery, np.array([0.25, 0.1]), 0.0, risk=risk
        )
        assert inside and not over


def test_kept_plans_are_rechecked_from_where_the_book_is(task, reach):
    """A model that predicts short moves keeps plans that overshoot: without the recheck the
    book of seed 0 falls; with it the overshooting push is refused from the book's real pose
    and replanned, and the book ends graspable."""
    short = _Short(task, 0.7)
    off = run_edge_episode(task, short, 0, reach=reach, trajectories=False, recheck=False)
    on = run_edge_episode(task, short, 0, reach=reach, trajectories=False)
    assert off.outcome == "fell" and off.vetoes == 0
    assert on.success and on.vetoes >= 1 and on.to_dict()["vetoes"] == on.vetoes
    assert len(on.plans) == on.replans + 1 and on.replans >= on.vetoes
    with pytest.raises(InputError, match="recheck must be True or False"):
        run_edge_episode(task, short, 0, reach=reach, recheck="yes")  # type: ignore[arg-type]
