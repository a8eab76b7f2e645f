"""The task-free searches on toy problems: A*, greedy, and sampling in one and two steps."""

import math
from dataclasses import dataclass

import numpy as np

from probaff.planning.search import astar, greedy, sample_best, sample_two_steps

STEPS = np.array([1.0, 3.0, -1.0])


class Line:
    """States are positions x (1,) on a line, actions move by +1, +3 or -1; the goal is x = 10."""

    def __init__(self, goal=10.0, walls=()):
        self.goal, self.walls, self.calls, self.sizes = goal, set(walls), 0, []

    def successors(self, states):
        self.calls += 1
        self.sizes.append(len(states))
        parent = np.repeat(np.arange(len(states)), len(STEPS))
        action = np.tile(STEPS, len(states))
        child = states[parent] + action[:, None]
        ok = np.array([float(c[0]) not in self.walls for c in child], dtype=bool)
        return parent[ok], action[ok], child[ok]

    def is_goal(self, states):
        return np.asarray(states)[..., 0] == self.goal

    def heuristic(self, states):
        return np.ceil(np.abs(self.goal - np.asarray(states)[..., 0]) / 3.0)

    def shortfall(self, states):
        return np.abs(self.goal - np.asarray(states)[..., 0])

    def key(self, state):
        return round(float(state[0]))


def test_astar_finds_a_shortest_path():
    line = Line()
    found = astar(line, np.zeros(1), budget=10, batch=1, max_expansions=100)
    assert found.reached_goal and len(found.actions) == 4 == math.ceil(10 / 3)
    assert sum(found.actions) == 10.0
    np.testing.assert_array_equal(found.states[:, 0], np.cumsum(found.actions))
    assert found.expansions == line.calls


def test_astar_batches_its_expansions():
    line = Line()
    found = astar(line, np.zeros(1), budget=10, batch=4, max_expansions=100)
    assert found.reached_goal and sum(found.actions) == 10.0
    assert max(line.sizes) > 1 and line.calls <= found.expansions


def test_astar_returns_the_closest_partial_path_within_its_limits():
    short = astar(Line(), np.zeros(1), budget=2, batch=1, max_expansions=100)
    assert not short.reached_goal and short.actions == (3.0, 3.0)
    few = astar(Line(), np.zeros(1), budget=10, batch=1, max_expansions=1)
    assert not few.reached_goal and few.expansions == 1 and few.actions == (3.0,)
    walled = astar(Line(walls={1.0, 3.0, -1.0}), np.zeros(1), budget=5, batch=1, max_expansions=9)
    assert walled.actions == () and walled.states.shape == (0, 1) and not walled.reached_goal


def test_greedy_takes_the_step_closest_to_the_goal():
    one = greedy(Line(), np.zeros(1))
    assert one.actions == (3.0,) and one.expansions == 1 and not one.reached_goal
    last = greedy(Line(), np.array([9.0]))
    assert last.actions == (1.0,) and last.reached_goal
    stuck = greedy(Line(walls={1.0, 3.0, -1.0}), np.zeros(1))
    assert stuck.actions == () and stuck.states.shape == (0, 1)


@dataclass(frozen=True)
class Moves:
    """Candidate moves: `step` (C,) from state `state` (C,)."""

    step: np.ndarray
    state: np.ndarray

    def __len__(self):
        return len(self.step)


class Walk:
    """Sampled moves on a line: ranked by the distance to `via`, scored by the final x."""

    def __init__(self, seed=0, via=5.0, stuck_after_one=False):
        self.rng, self.via, self.stuck = np.random.default_rng(seed), via, stuck_after_one
        self.predictions = []

    def sample(self, states, n, allow_empty):
        rows = len(np.atleast_1d(states))
        if allow_empty and self.stuck:
            rows = 0  # no second move from any state
        return Moves(self.rng.uniform(-4, 4, n * rows), np.repeat(np.arange(rows), n))

    def predict(self, states, moves):
        self.predictions.append(len(moves))
        return states + moves.step

    def rank(self, states):
        return np.abs(states - self.via)

    def score(self, states):
        return states


def test_sampling_in_one_step_takes_the_best_scored_move():
    walk = Walk()
    plan = sample_best(walk, np.array(0.0), 20)
    (moves,) = plan.candidates
    assert plan.chosen == (int(np.argmax(moves.step)),) and walk.predictions == [20]
    assert plan.score == moves.step.max() == plan.predicted[0]


def test_sampling_in_two_steps_keeps_the_closest_then_scores_the_end():
    walk = Walk(seed=1, via=-2.0)
    plan = sample_two_steps(walk, np.array(0.0), 30, 3, 10)
    first, second = plan.candidates
    kept = np.argsort(np.abs(first.step + 2.0), kind="stable")[:3]
    assert plan.chosen[0] in kept and walk.predictions == [30, 30]
    ends = first.step[kept][second.state] + second.step
    assert plan.score == ends.max() == plan.predicted[1]
    assert plan.predicted[0] == first.step[plan.chosen[0]]


def test_sampling_in_two_steps_falls_back_to_one_without_a_second_move():
    walk = Walk(seed=2, stuck_after_one=True)
    plan = sample_two_steps(walk, np.array(0.0), 8, 2, 5)
    assert len(plan.candidates) == 1 and walk.predictions == [8]
    assert plan.score == plan.candidates[0].step.max() == plan.predicted[0]


def test_a_planner_is_a_named_search():
    from probaff.planning.push_to_edge import EDGE_SEARCHES, plan_astar, plan_greedy
    from probaff.planning.tool_push import plan_single_push, plan_tool_push

    assert repr(plan_astar) == "EdgePlanner('astar')" and plan_greedy.name == "greedy"
    assert {"astar": plan_astar, "greedy": plan_greedy} == EDGE_SEARCHES
    assert repr(plan_tool_push) == "ToolPushPlanner('two_step')"
    assert plan_single_push.name == "single_step"
