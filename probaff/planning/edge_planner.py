"""A* over push transitions to a graspable book pose (chapter 4), and a greedy planner.

A node is a book pose; its children are the outcomes of the candidate pushes of
`EdgeTask.candidate_pushes` that the arm can reach and whose hand start clears the battery,
as a transition model predicts them. Each push costs 1; the heuristic
`EdgeTask.heuristic` is admissible when no push moves the book farther than
``search.step_bound``. The closed set discretises the pose (``search.xy_resolution``, and the
yaw modulo pi in ``search.yaw_resolution`` bins, the book's footprint being symmetric).

Pruning. The mean-only planner drops a child whose predicted centre comes within
``search.safety_margin`` of a table edge or whose footprint overlaps the battery, and it only
counts goals whose centre is that margin farther inside the edge than the task needs. The
risk-aware planner also draws ``risk.samples`` outcomes from the model's predictive
distribution and drops a child when the fraction of draws that fall off the table, or that
overlap the battery, exceeds its bound; a deterministic model's single outcome gives
probabilities of 0 or 1.

Batching. ``search.batch`` nodes of lowest f (ties broken by lower h, then by less progress
missing) are expanded together and all their candidates are predicted in one call. A node is
tested for the goal when it is generated; the search returns the first goal it generates (its
depth is minimal up to the batch and the discretisation) or, after ``search.max_expansions``,
the path to the node closest to a goal.
"""

from __future__ import annotations

import heapq
import itertools
import math
import time
from dataclasses import dataclass, field

import numpy as np

from probaff._checks import check_count
from probaff.errors import InputError
from probaff.planning.edge_task import EdgeTask
from probaff.planning.edge_transitions import (
    EdgeTransition,
    PushReachability,
    check_edge_transition,
    checked_prediction,
)

__all__ = ["EdgePlan", "plan_astar", "plan_greedy"]


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


@dataclass(order=True)
class _Node:
    priority: tuple[float, float, float, int]
    pose: np.ndarray = field(compare=False)
    g: int = field(compare=False)
    parent: _Node | None = field(compare=False, default=None)
    yaw: float = field(compare=False, default=0.0)


def _key(task: EdgeTask, pose: np.ndarray) -> tuple[int, int, int]:
    s = task.search
    bins = max(1, round(math.pi / s.yaw_resolution))
    return (
        round(float(pose[0]) / s.xy_resolution),
        round(float(pose[1]) / s.xy_resolution),
        round((float(pose[2]) % math.pi) / math.pi * bins) % bins,
    )


def _expand(
    task: EdgeTask,
    transition: EdgeTransition,
    reach: PushReachability,
    poses: np.ndarray,
    battery: np.ndarray,
    risk: bool,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Predict every admissible candidate push of B book poses in one call.

    Returns:
        ``(parent, yaw, child)``: (n,) index of the parent pose, (n,) push yaw and (n, 3)
        predicted child pose of each surviving candidate.
    """
    origins, yaws = task.candidate_pushes(poses)  # (B, C, 2), (C,)
    B, C = origins.shape[:2]
    yaw_bc = np.broadcast_to(yaws, (B, C))
    ok = reach(origins, yaw_bc) & ~task.hand_hits_battery(origins, yaw_bc, battery)
    parent, col = np.nonzero(ok)
    if len(parent) == 0:
        return parent, np.zeros(0), np.zeros((0, 3))
    n_samples = task.risk.samples if risk else 0
    pred = checked_prediction(
        transition,
        transition.predict(
            poses[parent], origins[parent, col], yaws[col], battery, n_samples=n_samples
        ),
        len(parent),
        n_samples,
    )
    child = pred.mean
    margin = task.search.safety_margin
    if risk and pred.samples is not None:
        p_fall = task.fallen(pred.samples).mean(0)
        p_hit = task.collides(pred.samples, battery).mean(0)
        keep = (p_fall <= task.risk.max_fall) & (p_hit <= task.risk.max_collision)
        keep &= ~task.fallen(child, margin)
    else:
        keep = ~task.fallen(child, margin) & ~task.collides(child, battery)
    return parent[keep], yaws[col][keep], child[keep]


def _path(node: _Node) -> tuple[tuple[float, ...], np.ndarray]:
    yaws, poses = [], []
    while node.parent is not None:
        yaws.append(node.yaw)
        poses.append(node.pose)
        node = node.parent
    return tuple(reversed(yaws)), np.array(list(reversed(poses))).reshape(-1, 3)


def plan_astar(
    task: EdgeTask,
    transition: EdgeTransition,
    book: np.ndarray,
    battery: np.ndarray,
    reach: PushReachability,
    *,
    budget: int | None = None,
    risk: bool = False,
) -> EdgePlan:
    """Plan pushes from a book pose to a graspable pose by A*.

    Args:
        task: The task.
        transition: The model of the pushes' outcomes.
        book: (3,) world book pose.
        battery: (3,) world battery pose.
        reach: The arm's push reachability.
        budget: Most pushes in the plan (the episode's remaining budget); ``task.budget``
            by default.
        risk: Prune by the predictive distribution's P(fall) and P(collision).

    Returns:
        The plan; ``reaches_goal`` is False when no goal was found within the search limits
        (the plan then leads to the pose closest to a goal, possibly empty).

    Raises:
        InputError: For a `task`, `transition` or `reach` of the wrong kind, a malformed
            pose, a book or battery off the table, a book overlapping the battery, a budget
            that is not a positive integer, or a transition whose predictions are not finite.
    """
    start_time = time.perf_counter()
    book, battery = _check_planner_args(task, transition, book, battery, reach)
    budget = check_count("budget (pushes left)", task.budget if budget is None else budget)
    calls0 = getattr(transition, "calls", 0)
    tie = itertools.count()

    h0 = float(task.heuristic(book))
    root = _Node((h0, h0, float(task.progress(book)), next(tie)), book, 0)
    if bool(task.graspable(book)):
        return EdgePlan((), np.zeros((0, 3)), True, 0, time.perf_counter() - start_time)
    open_: list[_Node] = [root]
    closed: set[tuple[int, int, int]] = set()
    best: _Node | None = None
    expansions = 0
    goal: _Node | None = None
    while open_ and goal is None and expansions < task.search.max_expansions:
        batch: list[_Node] = []
        while open_ and len(batch) < task.search.batch:
            n = heapq.heappop(open_)
            k = _key(task, n.pose)
            if k in closed or n.g >= budget:
                continue
            closed.add(k)
            batch.append(n)
        if not batch:
            break
        expansions += len(batch)
        parent, yaws, child = _expand(
            task, transition, reach, np.stack([n.pose for n in batch]), battery, risk
        )
        goals = task.graspable(child, task.search.safety_margin)
        hs, missing = task.heuristic(child), task.progress(child)
        for i in range(len(child)):
            g = batch[parent[i]].g + 1
            c = _Node(
                (g + float(hs[i]), float(hs[i]), float(missing[i]), next(tie)),
                child[i],
                g,
                batch[parent[i]],
                float(yaws[i]),
            )
            if goals[i]:
                if goal is None or c.g < goal.g:
                    goal = c
                continue
            if _key(task, c.pose) in closed:
                continue
            if best is None or c.priority[1:3] < best.priority[1:3]:
                best = c
            heapq.heappush(open_, c)
    end = goal or best or root
    yaws_out, predicted = _path(end)
    return EdgePlan(
        yaws_out,
        predicted,
        goal is not None,
        expansions,
        time.perf_counter() - start_time,
        getattr(transition, "calls", 0) - calls0,
    )


def plan_greedy(
    task: EdgeTask,
    transition: EdgeTransition,
    book: np.ndarray,
    battery: np.ndarray,
    reach: PushReachability,
    *,
    budget: int | None = None,
    risk: bool = False,
) -> EdgePlan:
    """Choose the single push whose predicted outcome is closest to a goal.

    Closeness is `EdgeTask.progress` (what the book lacks along x); a goal wins outright. The
    arguments are those of `plan_astar`.

    Returns:
        A plan of at most one push.

    Raises:
        InputError: As `plan_astar`.
    """
    start_time = time.perf_counter()
    book, battery = _check_planner_args(task, transition, book, battery, reach)
    check_count("budget (pushes left)", task.budget if budget is None else budget)
    if bool(task.graspable(book)):
        return EdgePlan((), np.zeros((0, 3)), True, 0, time.perf_counter() - start_time)
    calls0 = getattr(transition, "calls", 0)
    _, yaws, child = _expand(task, transition, reach, book[None], battery, risk)
    if len(child) == 0:
        calls = getattr(transition, "calls", 0) - calls0
        return EdgePlan((), np.zeros((0, 3)), False, 1, time.perf_counter() - start_time, calls)
    goals = task.graspable(child, task.search.safety_margin)
    score = np.where(goals, -1.0, task.progress(child))
    i = int(np.argmin(score))
    return EdgePlan(
        (float(yaws[i]),),
        child[i : i + 1],
        bool(goals[i]),
        1,
        time.perf_counter() - start_time,
        getattr(transition, "calls", 0) - calls0,
    )


def _check_planner_args(
    task: EdgeTask,
    transition: EdgeTransition,
    book: np.ndarray,
    battery: np.ndarray,
    reach: PushReachability,
) -> tuple[np.ndarray, np.ndarray]:
    if not isinstance(task, EdgeTask):
        raise InputError(f"task must be an EdgeTask (load_edge_task()), got {type(task).__name__}.")
    check_edge_transition(transition)
    if not isinstance(reach, PushReachability):
        raise InputError(
            f"reach must be the arm's PushReachability(task), got {type(reach).__name__}."
        )
    return task.check_start(book, battery)
