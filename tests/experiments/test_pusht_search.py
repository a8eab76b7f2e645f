"""Push-T's planner on probaff's one planning stack: `probaff.planning.search` and `Transition`.

`plan_push` (now `sample_best` and `sample_two_steps` over `TeeSearch`) against the beam search
Push-T used to run on its own, written out here: the same primitive, predicted pose, score and
random draws, greedy and two pushes deep, with and without the risk term. And a transition
that is not one, or that leaves out what Push-T needs, is refused by name.

Covers probaff.experiments.pusht.planner and probaff.experiments.pusht.transitions.
"""

import numpy as np
import pytest

from probaff.errors import InputError
from probaff.experiments.pusht.geometry import (
    AGENT_RADIUS,
    ARENA,
    KEYPOINTS,
    distance_to_tee,
    keypoint_cost,
    to_world,
)
from probaff.experiments.pusht.models import QuasiStaticTee
from probaff.experiments.pusht.planner import Node, SearchSettings, plan_push
from probaff.experiments.pusht.primitives import PrimitiveSettings, push_frames, sample_primitives
from probaff.experiments.pusht.transitions import ModelTransition, TeePushes
from probaff.planning.transitions import Transition, TransitionPrediction

RADIUS = float(np.sqrt((KEYPOINTS**2).sum(axis=1).mean()))


class Wobbly:
    """A deterministic transition whose spread differs from push to push."""

    name = "wobbly"

    def __init__(self):
        self.inner = ModelTransition(QuasiStaticTee(sigma=np.array([0.5, 1.0, 0.01])))

    def predict(self, pushes, *, n_samples=0, rng=None):
        pred = self.inner.predict(pushes)
        std = pred.effect_std * (1 + np.abs(np.sin(pushes.prims[:, :1, None] * 7)))
        return TransitionPrediction(pred.mean, effect_std=std, pusher=pred.pusher)


def _sample(rng, pose, n, s):
    prims = sample_primitives(rng, 3 * n, s)
    start = push_frames(prims, s)["start"]
    world = to_world(pose, start)
    ok = (distance_to_tee(start)[0] >= AGENT_RADIUS + s.gap - 1e-6) & np.all(
        (world >= ARENA[0]) & (world <= ARENA[1]), axis=-1
    )
    return prims[ok][:n]


def _steps(pose, agent, prims, s):
    start = to_world(pose, push_frames(prims, s)["start"])
    travel = np.linalg.norm(start - agent, axis=-1) * 1.3
    return travel / s.approach_speed + (s.gap + prims[:, 2]) / s.push_speed + s.wait + s.settle


def _expand(transition, pose, agent, vel, prims, s):
    k = len(prims)
    rep = lambda a: np.repeat(np.asarray(a)[None], k, 0)  # noqa: E731
    pred = transition.predict(TeePushes(rep(pose), rep(agent), rep(vel), prims, s))
    std = pred.effect_std[:, 0]
    spread = np.sqrt(std[:, 0] ** 2 + std[:, 1] ** 2 + (RADIUS * std[:, 2]) ** 2)
    return pred.mean[:, 0], pred.pusher, spread


def _reference(node, goal, transition, rng, search, s):
    """The beam search as Push-T ran it on its own before it joined probaff.planning."""
    first = _sample(rng, node.pose, search.candidates, s)
    if len(first) == 0:
        first = sample_primitives(rng, 1, s)
    poses, pushers, spread = _expand(transition, node.pose, node.agent, node.agent_vel, first, s)
    steps = _steps(node.pose, node.agent, first, s)
    cost = np.array([float(keypoint_cost(p, goal)) for p in poses])
    score = cost + search.risk * spread + search.step_cost * steps
    if search.depth == 2:
        for i in np.argsort(score)[: search.beam]:
            second = _sample(rng, poses[i], search.children, s)
            if len(second) == 0:
                continue
            grand, _, _ = _expand(transition, poses[i], pushers[i, :2], pushers[i, 2:], second, s)
            steps2 = _steps(poses[i], pushers[i, :2], second, s)
            cost2 = np.array([float(keypoint_cost(g, goal)) for g in grand])
            best = float(np.min(cost2 + search.step_cost * steps2))
            extra = search.risk * spread[i] + search.step_cost * steps[i]
            score[i] = min(score[i], best + extra)
    j = int(np.argmin(score))
    return first[j], poses[j], float(score[j])


@pytest.mark.parametrize(("depth", "risk"), [(1, 0.0), (2, 0.0), (2, 1.5)])
def test_plan_push_is_the_beam_search_it_replaced(depth, risk):
    goal = np.array([256.0, 256.0, np.pi / 4])
    search = SearchSettings(candidates=32, beam=3, children=8, depth=depth, risk=risk)
    s = PrimitiveSettings()
    for k in range(4):
        node = Node(
            np.array([180.0 + 25 * k, 300.0 - 20 * k, 0.6 * k]),
            np.array([90.0 + 15 * k, 420.0]),
            np.zeros(2),
        )
        ours, theirs = np.random.default_rng(k), np.random.default_rng(k)
        got = plan_push(node, goal, Wobbly(), ours, search, s)
        want = _reference(node, goal, Wobbly(), theirs, search, s)
        np.testing.assert_array_equal(got[0], want[0])
        np.testing.assert_array_equal(got[1], want[1])
        assert got[2] == want[2]
        assert ours.random() == theirs.random()  # the same draws, in the same order


class NoPusher:
    name = "no-pusher"

    def predict(self, pushes, *, n_samples=0, rng=None):
        return TransitionPrediction(pushes.poses[:, None].copy())


def test_transitions_are_planning_transitions_and_incomplete_ones_are_refused():
    model = ModelTransition(QuasiStaticTee(sigma=np.full(3, 0.1)))
    assert isinstance(model, Transition) and model.name == "analytic"
    node = Node(np.array([230.0, 256.0, 0.0]), np.array([100.0, 100.0]), np.zeros(2))
    goal, rng, s = np.array([256.0, 256.0, 0.0]), np.random.default_rng(0), PrimitiveSettings()
    with pytest.raises(InputError, match="transition must be a push transition model"):
        plan_push(node, goal, object(), rng, SearchSettings(), s)
    with pytest.raises(InputError, match="'no-pusher' must predict the agent's state"):
        plan_push(node, goal, NoPusher(), rng, SearchSettings(depth=1), s)
    with pytest.raises(InputError, match=r"TeePushes\.agents"):
        TeePushes(np.zeros((2, 3)), np.zeros((1, 2)), np.zeros((2, 2)), np.zeros((2, 3)), None)
