"""How a plan is searched, whatever the task: A*, the greedy one step, and sampling in two steps.

A task hands a search its states as arrays and answers its questions; the search knows nothing
of books, boxes or pushes. What is scored (a `probaff.planning.transitions.Transition`) lives
in the task's answers.

Graph searches (`astar`, `greedy`) read a `SearchProblem`: the successors of a batch of states
(one batched prediction), which states are goals, an admissible heuristic, a shortfall (how
far a state still is from a goal, for tie-breaks and the greedy choice) and a hashable key that
discretises a state for the closed set. Each action costs 1.

- `astar` expands ``batch`` nodes of lowest f together (ties broken by lower h, then by lower
  shortfall, then by age), asks for all their successors in one call, tests a node for the goal
  when it is generated, and returns the first goal it generates or, after ``max_expansions``,
  the path to the generated node closest to a goal (lowest h, then shortfall). Nodes ``budget``
  actions deep are not expanded.
- `greedy` takes the one action whose successor is a goal or, failing one, has the lowest
  shortfall.

Sampling searches (`sample_best`, `sample_two_steps`) read a `SamplingProblem`: candidate
actions sampled from a batch of states, their predicted successors, a rank of intermediate
states (lower is kept) and a score of final states (higher is better).

- `sample_best` samples ``n`` actions and takes the best scored successor.
- `sample_two_steps` samples ``n_first`` actions, keeps the ``n_keep`` successors of lowest
  rank, samples ``n_second`` actions from each, and takes the sequence whose final successor
  scores best; when no kept state has an action, the best first action alone.

A task's planner is a `SearchPlanner`: a named search, which the task's subclass runs on its own
problem (`probaff.planning.push_to_edge.EdgePlanner`, `probaff.planning.tool_push
.ToolPushPlanner`).

Covered by tests/planning/test_planning_search.py.
"""

from __future__ import annotations

import heapq
import itertools
from collections.abc import Callable, Hashable
from dataclasses import dataclass, field
from typing import Any, Generic, Protocol, TypeVar

import numpy as np

__all__ = [
    "Candidates",
    "SampledPlan",
    "SamplingProblem",
    "SearchPlanner",
    "SearchProblem",
    "SearchResult",
    "astar",
    "greedy",
    "sample_best",
    "sample_two_steps",
]


class SearchProblem(Protocol):
    """A task's states and actions as a graph search sees them (each action costs 1)."""

    def successors(self, states: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Every admissible action from B states, predicted in one call.

        Args:
            states: (B, ...) states.

        Returns:
            ``(parent, action, child)``: (n,) index of each successor's state, (n,) its
            action and (n, ...) the successor.
        """
        ...

    def is_goal(self, states: np.ndarray) -> np.ndarray:
        """(n,) bool: which of the (n, ...) states are goals."""
        ...

    def heuristic(self, states: np.ndarray) -> np.ndarray:
        """(n,) admissible lower bounds on the actions from (n, ...) states to a goal."""
        ...

    def shortfall(self, states: np.ndarray) -> np.ndarray:
        """(n,) how far (n, ...) states still are from a goal (0 at a goal; lower is closer)."""
        ...

    def key(self, state: np.ndarray) -> Hashable:
        """The closed-set cell of one state."""
        ...


@dataclass(frozen=True)
class SearchResult:
    """A path found by a graph search.

    Attributes:
        actions: The actions, in order.
        states: (n, ...) the predicted state after each action.
        reached_goal: The last state is a goal.
        expansions: States expanded.
    """

    actions: tuple[float, ...]
    states: np.ndarray
    reached_goal: bool
    expansions: int


@dataclass(order=True)
class _Node:
    priority: tuple[float, float, float, int]
    state: np.ndarray = field(compare=False)
    g: int = field(compare=False)
    parent: _Node | None = field(compare=False, default=None)
    action: float = field(compare=False, default=0.0)


def _path(node: _Node, width: int) -> tuple[tuple[float, ...], np.ndarray]:
    actions, states = [], []
    while node.parent is not None:
        actions.append(node.action)
        states.append(node.state)
        node = node.parent
    return tuple(reversed(actions)), np.array(list(reversed(states))).reshape(-1, width)


def astar(
    problem: SearchProblem,
    root: np.ndarray,
    *,
    budget: int,
    batch: int,
    max_expansions: int,
) -> SearchResult:
    """Batched A* from `root` (see the module docstring).

    Args:
        problem: The task's answers.
        root: (D,) the start state; the caller has checked that it is not a goal.
        budget: Most actions in a path (a positive integer).
        batch: Nodes expanded together (a positive integer).
        max_expansions: Nodes expanded before the search returns its best partial path.

    Returns:
        The path to the first goal generated, else to the generated node closest to a goal
        (empty when nothing was generated).
    """
    tie = itertools.count()
    h0 = float(problem.heuristic(root))
    root_node = _Node((h0, h0, float(problem.shortfall(root)), next(tie)), root, 0)
    open_: list[_Node] = [root_node]
    closed: set[Hashable] = set()
    best: _Node | None = None
    expansions = 0
    goal: _Node | None = None
    while open_ and goal is None and expansions < max_expansions:
        nodes: list[_Node] = []
        while open_ and len(nodes) < batch:
            n = heapq.heappop(open_)
            k = problem.key(n.state)
            if k in closed or n.g >= budget:
                continue
            closed.add(k)
            nodes.append(n)
        if not nodes:
            break
        expansions += len(nodes)
        parent, actions, child = problem.successors(np.stack([n.state for n in nodes]))
        goals = problem.is_goal(child)
        hs, short = problem.heuristic(child), problem.shortfall(child)
        for i in range(len(child)):
            g = nodes[parent[i]].g + 1
            c = _Node(
                (g + float(hs[i]), float(hs[i]), float(short[i]), next(tie)),
                child[i],
                g,
                nodes[parent[i]],
                float(actions[i]),
            )
            if goals[i]:
                if goal is None or c.g < goal.g:
                    goal = c
                continue
            if problem.key(c.state) in closed:
                continue
            if best is None or c.priority[1:3] < best.priority[1:3]:
                best = c
            heapq.heappush(open_, c)
    actions_out, states = _path(goal or best or root_node, root.shape[-1])
    return SearchResult(actions_out, states, goal is not None, expansions)


def greedy(problem: SearchProblem, root: np.ndarray) -> SearchResult:
    """The one action whose successor is a goal or, failing one, has the lowest shortfall.

    Args:
        problem: The task's answers.
        root: (D,) the start state; the caller has checked that it is not a goal.

    Returns:
        A path of at most one action (none when `root` has no successor); one expansion.
    """
    _, actions, child = problem.successors(root[None])
    if len(child) == 0:
        return SearchResult((), np.zeros((0, root.shape[-1])), False, 1)
    goals = problem.is_goal(child)
    score = np.where(goals, -1.0, problem.shortfall(child))
    i = int(np.argmin(score))
    return SearchResult((float(actions[i]),), child[i : i + 1], bool(goals[i]), 1)


class Candidates(Protocol):
    """Candidate actions sampled from several states."""

    @property
    def state(self) -> np.ndarray:
        """(C,) index of the state each candidate acts from."""
        ...

    def __len__(self) -> int: ...


C = TypeVar("C", bound=Candidates)
S = TypeVar("S", bound=Callable[..., Any])


class SearchPlanner(Generic[S]):
    """A task's planner: a named search that the task runs on its own states.

    A task subclasses it with a ``__call__`` that checks its arguments, poses its problem and
    runs `search` on it.

    Args:
        name: The planner's name.
        search: The search, ``search(problem, root, ...)``.
    """

    def __init__(self, name: str, search: S) -> None:
        self.name, self.search = name, search

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.name!r})"


class SamplingProblem(Protocol[C]):
    """A task's states and actions as a sampling search sees them."""

    def sample(self, states: np.ndarray, n: int, allow_empty: bool) -> C:
        """Up to `n` candidate actions from each of (S, ...) states, grouped by state in order.

        With `allow_empty`, a state without an action gets none instead of an error.
        """
        ...

    def predict(self, states: np.ndarray, candidates: C) -> np.ndarray:
        """(C, ...) the predicted successor of each candidate from its (C, ...) state."""
        ...

    def rank(self, states: np.ndarray) -> np.ndarray:
        """(n,) rank of (n, ...) intermediate states; the lowest are kept."""
        ...

    def score(self, states: np.ndarray) -> np.ndarray:
        """(n,) score of (n, ...) final states; the highest wins."""
        ...


@dataclass(frozen=True)
class SampledPlan(Generic[C]):
    """A sequence chosen by a sampling search.

    Attributes:
        candidates: The candidates sampled and predicted at each step.
        chosen: The chosen candidate of each step, an index into its `candidates`.
        predicted: (S, ...) the predicted state after each chosen step.
        score: The score of the final predicted state.
    """

    candidates: tuple[C, ...]
    chosen: tuple[int, ...]
    predicted: np.ndarray
    score: float


def sample_best(problem: SamplingProblem[C], root: np.ndarray, n: int) -> SampledPlan[C]:
    """Of `n` sampled actions from `root`, the one whose successor scores best.

    Args:
        problem: The task's answers.
        root: (...) the start state.
        n: Candidates (a positive integer).

    Returns:
        One step; one prediction call.
    """
    cand = problem.sample(root, n, False)
    after = problem.predict(np.broadcast_to(root, (len(cand), *root.shape)), cand)
    score = problem.score(after)
    j = int(np.argmax(score))
    return SampledPlan((cand,), (j,), after[j : j + 1], float(score[j]))


def sample_two_steps(
    problem: SamplingProblem[C], root: np.ndarray, n_first: int, n_keep: int, n_second: int
) -> SampledPlan[C]:
    """Two sampled steps: keep the best-ranked first successors, then sample from each.

    Args:
        problem: The task's answers.
        root: (...) the start state.
        n_first: Actions sampled from `root`.
        n_keep: First successors kept (lowest rank), at most `n_first`.
        n_second: Actions sampled from each kept successor.

    Returns:
        Two steps, or one when no kept successor has an action; one prediction call per step.
    """
    first = problem.sample(root, n_first, False)
    after1 = problem.predict(np.broadcast_to(root, (len(first), *root.shape)), first)
    keep = np.argsort(problem.rank(after1), kind="stable")[:n_keep]
    second = problem.sample(after1[keep], n_second, True)
    if len(second) == 0:
        score1 = problem.score(after1)
        j = int(np.argmax(score1))
        return SampledPlan((first,), (j,), after1[j : j + 1], float(score1[j]))
    after2 = problem.predict(after1[keep][second.state], second)
    score = problem.score(after2)
    best = int(np.argmax(score))
    j = int(keep[second.state[best]])
    return SampledPlan(
        (first, second), (j, best), np.stack([after1[j], after2[best]]), float(score[best])
    )
