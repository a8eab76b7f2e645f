"""Planning pushes of the book to a graspable pose: A* and the greedy one step (chapter 4).

The search (`probaff.planning.search`) sees book poses as states. A node's children are the
outcomes of the candidate pushes of `EdgeTask.candidate_pushes` that the arm can reach
(`PushReachability`) and whose hand start clears the battery, as a transition model predicts
them (`predict_books`: the book and the battery are the transition's two objects, of which
the planner reads the book). Each push costs 1; the heuristic `EdgeTask.heuristic` is
admissible when no push moves the book farther than ``search.step_bound``. The closed set
discretises the pose (``search.xy_resolution``, and the yaw modulo pi in
``search.yaw_resolution`` bins, the book's footprint being symmetric).

Pruning. The mean-only planner drops a child whose predicted centre comes within
``search.safety_margin`` of a table edge or whose footprint overlaps the battery, and it only
counts goals whose centre is that margin farther inside the edge than the task needs. The
risk-aware planner also draws ``risk.samples`` outcomes from the model's predictive
distribution and drops a child when the fraction of draws that fall off the table, or that
overlap the battery, exceeds its bound; a deterministic model's single outcome gives
probabilities of 0 or 1.

Batching. ``search.batch`` nodes are expanded together and all their candidates are predicted
in one call; the search returns the first goal it generates (its depth is minimal up to the
batch and the discretisation) or, after ``search.max_expansions``, the path to the node
closest to a goal.

Covered by tests/planning/push_to_edge/test_edge_planners.py.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import torch

from probaff._checks import check_count, check_positive
from probaff.planning._checks import check_instance
from probaff.planning.push_to_edge.task import EdgeTask, check_task
from probaff.planning.search import SearchPlanner, SearchResult, astar, greedy
from probaff.planning.transitions import (
    PushBatch,
    Transition,
    TransitionPrediction,
    check_transition,
    checked_prediction,
)
from probaff.sim.arm import Arm, load_arm

__all__ = [
    "EdgePlan",
    "EdgePlanner",
    "PushReachability",
    "plan_astar",
    "plan_greedy",
    "predict_books",
    "push_admissible",
]


class PushReachability:
    """Whether the arm can execute straight pushes, by IK, cached per cell.

    A push's start is snapped to a cell of `xy_resolution` and its yaw to one of `yaw_bins`
    (`snap`); the answer for a cell is computed once, by IK of the whole snapped push, so it
    does not depend on which pushes were asked before. An episode executes the snapped push,
    so the arm runs exactly the push whose reachability the planner was told.

    Args:
        task: The task (the world's arm, the push length).
        xy_resolution: Cell size (m), a finite number > 0.
        yaw_bins: Yaw bins per turn, a positive integer.

    Raises:
        InputError: For a `task` that is not an `EdgeTask`, an `xy_resolution` that is not
            > 0 or a `yaw_bins` that is not a positive integer.
    """

    def __init__(self, task: EdgeTask, xy_resolution: float = 0.01, yaw_bins: int = 64) -> None:
        task = check_task(task)
        check_positive("PushReachability xy_resolution (m)", xy_resolution)
        self.bins = check_count("PushReachability yaw_bins", yaw_bins)
        self.res = float(xy_resolution)
        self.arm: Arm = load_arm(task.world.arm)
        self.distance = task.push_distance
        self._cache: dict[tuple[int, int, int], bool] = {}

    def _keys(self, origins: np.ndarray, yaws: np.ndarray) -> np.ndarray:
        ix = np.round(origins[..., 0] / self.res).astype(np.int64)
        iy = np.round(origins[..., 1] / self.res).astype(np.int64)
        iw = np.round(yaws / (2 * math.pi) * self.bins).astype(np.int64) % self.bins
        return np.stack([ix, iy, np.broadcast_to(iw, ix.shape)], -1)

    def snap(self, origins: np.ndarray, yaws: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The pushes whose reachability a cell stands for.

        Args:
            origins: (..., 2) world hand starts.
            yaws: (...,) push yaws, broadcastable.

        Returns:
            ``(origins, yaws)`` snapped to the cell centres and yaw bins.
        """
        keys = self._keys(origins, np.broadcast_to(yaws, origins.shape[:-1]))
        return keys[..., :2] * self.res, keys[..., 2] * (2 * math.pi / self.bins)

    def __call__(self, origins: np.ndarray, yaws: np.ndarray) -> np.ndarray:
        """Reachability of pushes.

        Args:
            origins: (..., 2) world hand starts.
            yaws: (...,) push yaws, broadcastable.

        Returns:
            (...,) bool.
        """
        keys = self._keys(origins, np.broadcast_to(yaws, origins.shape[:-1]))
        flat = [(int(a), int(b), int(c)) for a, b, c in keys.reshape(-1, 3)]
        missing = sorted({k for k in flat if k not in self._cache})
        if missing:
            m = torch.tensor(missing, dtype=torch.float64)
            xy = m[:, :2] * self.res
            yaw = m[:, 2] * (2 * math.pi / self.bins)
            ok = self.arm.solve_pushes(xy, yaw, self.distance).ok.numpy()
            self._cache.update(zip(missing, map(bool, ok), strict=True))
        ok = np.fromiter((self._cache[k] for k in flat), dtype=np.bool_, count=len(flat))
        return ok.reshape(keys.shape[:-1])


def predict_books(
    task: EdgeTask,
    transition: Transition,
    book: np.ndarray,
    origins: np.ndarray,
    yaws: np.ndarray,
    battery: np.ndarray,
    n_samples: int = 0,
) -> TransitionPrediction:
    """Where N pushes leave the book, as `transition` predicts them (checked).

    The task's state is the book and the battery; the transition sees them as its two
    objects (the book pushed, the battery where it stands) and this returns the book's part.

    Args:
        task: The task (objects, push length).
        transition: The model of the pushes.
        book: (N, 3) world book poses before each push.
        origins: (N, 2) world hand starts.
        yaws: (N,) world push yaws (rad).
        battery: (3,) world battery pose.
        n_samples: Draws from the predictive distribution (0: none).

    Returns:
        The book's predicted poses: mean (N, 3), samples (S, N, 3) or ``None``.

    Raises:
        InputError: For a prediction of the wrong shape or that is not finite.
    """
    n = len(book)
    poses = np.stack([book, np.broadcast_to(battery, (n, 3))], axis=1)  # (N, 2, 3)
    pushes = PushBatch((task.book, task.battery), poses, origins, yaws, task.push_distance)
    pred = checked_prediction(
        transition, transition.predict(pushes, n_samples=n_samples), (n, 2), n_samples
    )
    samples = None if pred.samples is None else pred.samples[:, :, 0]
    return TransitionPrediction(pred.mean[:, 0], samples)


@dataclass(frozen=True)
class EdgePlan:
    """A sequence of pushes and where the model expects each to leave the book.

    Attributes:
        yaws: World yaws of the pushes, in order; each push starts from the book's pose at
            that time (`EdgeTask.candidate_pushes`).
        predicted: (n, 3) predicted book poses after each push.
        reaches_goal: The last predicted pose is a goal.
        expansions: Nodes expanded.
        seconds: Wall time spent planning.
        predictions: Calls of the transition model.
    """

    yaws: tuple[float, ...]
    predicted: np.ndarray
    reaches_goal: bool
    expansions: int
    seconds: float
    predictions: int = 0

    def __len__(self) -> int:
        return len(self.yaws)

    def rest(self) -> EdgePlan:
        """The plan without its first push."""
        return EdgePlan(
            self.yaws[1:],
            self.predicted[1:],
            self.reaches_goal,
            self.expansions,
            0.0,
            0,
        )


def _outcomes(
    task: EdgeTask,
    transition: Transition,
    battery: np.ndarray,
    risk: bool,
    books: np.ndarray,
    origins: np.ndarray,
    yaws: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """The predicted book poses of N pushes and whether a planner admits each.

    A push is admitted when its predicted centre stays ``search.safety_margin`` inside every
    edge and, for the mean-only planner, off the battery; the risk-aware planner (`risk`)
    also bounds the fractions of ``risk.samples`` draws that fall or hit the battery.

    Args:
        task: The task.
        transition: The planner's model of the pushes.
        battery: (3,) world battery pose.
        risk: The risk-aware planner's test.
        books: (N, 3) world book poses before the pushes.
        origins: (N, 2) world hand starts.
        yaws: (N,) world push yaws (rad).

    Returns:
        ``(child, keep)``: (N, 3) predicted mean poses and (N,) bool.
    """
    n_samples = task.risk.samples if risk else 0
    pred = predict_books(task, transition, books, origins, yaws, battery, n_samples)
    child = pred.mean
    margin = task.search.safety_margin
    if risk and pred.samples is not None:
        p_fall = task.fallen(pred.samples).mean(0)
        p_hit = task.collides(pred.samples, battery).mean(0)
        keep = (p_fall <= task.risk.max_fall) & (p_hit <= task.risk.max_collision)
        keep &= ~task.fallen(child, margin)
    else:
        keep = ~task.fallen(child, margin) & ~task.collides(child, battery)
    return child, keep


class _BookSearch:
    """The push-to-edge task as a `SearchProblem` over book poses (the battery stands)."""

    def __init__(
        self,
        task: EdgeTask,
        transition: Transition,
        reach: PushReachability,
        battery: np.ndarray,
        risk: bool,
    ) -> None:
        self.task, self.transition, self.reach = task, transition, reach
        self.battery, self.risk = battery, risk
        s = task.search
        self._bins = max(1, round(math.pi / s.yaw_resolution))

    def successors(self, poses: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Predict every admissible candidate push of B book poses in one call.

        Returns:
            ``(parent, yaw, child)``: (n,) index of the parent pose, (n,) push yaw and (n, 3)
            predicted child pose of each surviving candidate.
        """
        task, battery = self.task, self.battery
        origins, yaws = task.candidate_pushes(poses)  # (B, C, 2), (C,)
        B, C = origins.shape[:2]
        yaw_bc = np.broadcast_to(yaws, (B, C))
        ok = self.reach(origins, yaw_bc) & ~task.hand_hits_battery(origins, yaw_bc, battery)
        parent, col = np.nonzero(ok)
        if len(parent) == 0:
            return parent, np.zeros(0), np.zeros((0, 3))
        child, keep = _outcomes(
            task,
            self.transition,
            battery,
            self.risk,
            poses[parent],
            origins[parent, col],
            yaws[col],
        )
        return parent[keep], yaws[col][keep], child[keep]

    def is_goal(self, poses: np.ndarray) -> np.ndarray:
        """Goals with the planner's safety margin."""
        return self.task.graspable(poses, self.task.search.safety_margin)

    def heuristic(self, poses: np.ndarray) -> np.ndarray:
        """`EdgeTask.heuristic`."""
        return self.task.heuristic(poses)

    def shortfall(self, poses: np.ndarray) -> np.ndarray:
        """`EdgeTask.progress`."""
        return self.task.progress(poses)

    def key(self, pose: np.ndarray) -> tuple[int, int, int]:
        """The closed-set cell: position cells and the yaw modulo pi in bins."""
        s = self.task.search
        return (
            round(float(pose[0]) / s.xy_resolution),
            round(float(pose[1]) / s.xy_resolution),
            round((float(pose[2]) % math.pi) / math.pi * self._bins) % self._bins,
        )


def push_admissible(
    task: EdgeTask,
    transition: Transition,
    book: np.ndarray,
    battery: np.ndarray,
    origin: np.ndarray,
    yaw: float,
    *,
    risk: bool = False,
) -> bool:
    """Whether a planner would still take one push from where the book is now.

    The same test as the search's children get: the model's prediction of the
    push from `book` stays inside the safety margin and off the battery (or, with `risk`,
    within the risk bounds). An episode asks it before it executes the next push of a plan
    it kept, since that plan was predicted from where the book was expected to be.

    Args:
        task: The task.
        transition: The planner's model of the pushes.
        book: (3,) world book pose now.
        battery: (3,) world battery pose.
        origin: (2,) world hand start of the push.
        yaw: World push yaw (rad).
        risk: The risk-aware planner's test.

    Returns:
        True when the push is admitted.

    Raises:
        InputError: For a transition whose prediction is not finite or of the wrong shape.
    """
    _, keep = _outcomes(
        task,
        transition,
        np.asarray(battery, dtype=float),
        risk,
        np.asarray(book, dtype=float)[None],
        np.asarray(origin, dtype=float)[None],
        np.array([yaw], dtype=float),
    )
    return bool(keep[0])


Search = Callable[[_BookSearch, np.ndarray, int], SearchResult]
"""``search(problem, book, budget)``: a search of `probaff.planning.search` over book poses."""


class EdgePlanner(SearchPlanner[Search]):
    """A planner of pushes from a book pose to a graspable pose: a search over book poses.

    The planners are `plan_astar` and `plan_greedy` (named by their key of `EDGE_SEARCHES`);
    a call checks its arguments, returns an empty plan from a goal, and otherwise runs the
    search on the task's states.
    """

    def __call__(
        self,
        task: EdgeTask,
        transition: Transition,
        book: np.ndarray,
        battery: np.ndarray,
        reach: PushReachability,
        *,
        budget: int | None = None,
        risk: bool = False,
    ) -> EdgePlan:
        """Plan pushes of the book from `book` towards a graspable pose.

        Args:
            task: The task (its ``search`` options: batch, expansions, resolutions).
            transition: The model of the pushes' outcomes.
            book: (3,) world book pose.
            battery: (3,) world battery pose.
            reach: The arm's push reachability.
            budget: Most pushes in the plan (the episode's remaining budget); ``task.budget``
                by default.
            risk: Prune by the predictive distribution's P(fall) and P(collision).

        Returns:
            The plan; ``reaches_goal`` is False when no goal was found within the search
            limits (the plan then leads to the pose closest to a goal, possibly empty).

        Raises:
            InputError: For a `task`, `transition` or `reach` of the wrong kind, a malformed
                pose, a book or battery off the table, a book overlapping the battery, a
                budget that is not a positive integer, or a transition whose predictions are
                not finite.
        """
        start_time = time.perf_counter()
        check_task(task)
        check_transition(transition)
        check_instance(reach, PushReachability, "reach must be the arm's PushReachability(task)")
        book, battery = task.check_start(book, battery)
        budget = check_count("budget (pushes left)", task.budget if budget is None else budget)
        calls0 = getattr(transition, "calls", 0)
        if bool(task.graspable(book)):
            return EdgePlan((), np.zeros((0, 3)), True, 0, time.perf_counter() - start_time)
        found = self.search(_BookSearch(task, transition, reach, battery, risk), book, budget)
        return EdgePlan(
            found.actions,
            found.states,
            found.reached_goal,
            found.expansions,
            time.perf_counter() - start_time,
            getattr(transition, "calls", 0) - calls0,
        )


def _astar(problem: _BookSearch, book: np.ndarray, budget: int) -> SearchResult:
    s = problem.task.search
    return astar(problem, book, budget=budget, batch=s.batch, max_expansions=s.max_expansions)


plan_astar = EdgePlanner("astar", _astar)
"""A* over book poses (`probaff.planning.search.astar`, with the task's ``search`` options).

Call it as ``plan_astar(task, transition, book, battery, reach, *, budget=None, risk=False)``
(see `EdgePlanner.__call__`).
"""

plan_greedy = EdgePlanner("greedy", lambda problem, book, _: greedy(problem, book))
"""The single push whose predicted outcome is closest to a goal (`EdgeTask.progress`, what the
book lacks along x; a goal wins outright); the arguments are those of `plan_astar`.
"""
