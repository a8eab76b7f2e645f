"""One closed-loop push-to-edge episode in the simulator.

The planner plans from the observed book pose; the first planned push runs in the simulator
(the URDF arm's IK and the episode's own randomised physics, unknown to the planner) and the
book's new pose is observed. The rest of the plan is kept while the book lands within
``replan_distance`` of its prediction; otherwise the planner replans from where it is. With
``recheck`` (the default), each later push of a kept plan must also pass the planner's own
test of a search child from the book's pose then (`push_admissible`), or the planner replans
(a veto): the plan's later poses were predicted from where the book was expected to be, and
small errors that each stay under ``replan_distance`` add up. The episode succeeds when the
book is graspable (`EdgeTask.graspable`), and fails when it falls, when the planner finds no
admissible push, or after ``budget`` pushes.

Covered by tests/planning/push_to_edge/test_edge_episode.py.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field, replace
from typing import Any

import numpy as np

from probaff._checks import check_bool, check_count
from probaff.errors import InputError, UnreachablePoseError
from probaff.planning._checks import check_instance
from probaff.planning.push_to_edge.planners import (
    EdgePlan,
    EdgePlanner,
    PushReachability,
    plan_astar,
    plan_greedy,
    push_admissible,
)
from probaff.planning.push_to_edge.task import EdgeTask, check_task, sample_episode
from probaff.planning.transitions import Transition, check_transition
from probaff.sim.runner import PushSimulator
from probaff.sim.tabletop import SceneInstance

__all__ = ["EDGE_SEARCHES", "EdgeEpisode", "EdgeStep", "run_edge_episode"]

EDGE_SEARCHES: dict[str, EdgePlanner] = {"astar": plan_astar, "greedy": plan_greedy}
"""The searches an episode can use, by name."""

_MAX_UNREACHABLE = 5  # pushes the exact IK may reject in a row before the episode gives up


@dataclass(frozen=True)
class EdgeStep:
    """One executed push.

    Attributes:
        yaw: World push yaw (rad).
        origin: (2,) world hand start.
        before: (3,) book pose before.
        predicted: (3,) where the plan expected the book.
        after: (3,) where it landed.
        error: Distance (m) between the predicted and the landed position.
        replanned: The planner replanned after this push.
        fell: The book fell off the table.
        hand: (T, 3) executed world ``(x, y, yaw)`` of the hand.
        book_path: (T, 3) the book's world trajectory.
    """

    yaw: float
    origin: list[float]
    before: list[float]
    predicted: list[float]
    after: list[float]
    error: float
    replanned: bool
    fell: bool
    hand: list[list[float]] = field(default_factory=list)
    book_path: list[list[float]] = field(default_factory=list)


@dataclass(frozen=True)
class EdgeEpisode:
    """What happened in one episode.

    Attributes:
        seed: The episode's seed (its start and its physics).
        planner: A label.
        success: The book ended graspable.
        outcome: ``"success"``, ``"fell"``, ``"budget"`` or ``"stuck"`` (no admissible push).
        pushes: Pushes executed.
        replans: Plans made after the first.
        vetoes: Pushes of a kept plan that the planner's test refused from the book's pose
            then (``recheck``), each followed by a new plan.
        plans: Every plan's predicted poses, (n_i, 3) each, as lists.
        planning_seconds: Wall time of each planning call.
        start: (2, 3) book and battery poses at the start.
        final: (3,) the book's final pose.
        steps: The executed pushes.
    """

    seed: int
    planner: str
    success: bool
    outcome: str
    pushes: int
    replans: int
    vetoes: int
    plans: list[list[list[float]]]
    planning_seconds: list[float]
    start: list[list[float]]
    final: list[float]
    steps: list[EdgeStep]

    @property
    def mean_error(self) -> float:
        """Mean one-step prediction error (m) over the executed pushes (NaN if none)."""
        return float(np.mean([s.error for s in self.steps])) if self.steps else math.nan

    def to_dict(self) -> dict[str, Any]:
        """A JSON-able record."""
        return {**asdict(self), "mean_error": self.mean_error}


def _check_episode(
    task: Any, transition: Any, search: Any, seed: Any, simulator: Any, reach: Any, recheck: Any
) -> int:
    """The episode's seed, or `InputError` for any argument of `run_edge_episode` it refuses."""
    check_bool("recheck", recheck)
    if not isinstance(search, str) or search not in EDGE_SEARCHES:
        raise InputError(f"unknown search {search!r}; choose one of {sorted(EDGE_SEARCHES)}.")
    seed = check_count("seed", seed, minimum=0)
    check_task(task)
    check_transition(transition)
    if simulator is not None:
        what = "simulator must be a PushSimulator(task.scene, task.world) or None"
        check_instance(simulator, PushSimulator, what)
    if reach is not None:
        what = "reach must be the arm's PushReachability(task) or None"
        check_instance(reach, PushReachability, what)
    return seed


def _next_push(
    task: EdgeTask, reach: PushReachability, poses: np.ndarray, plan: EdgePlan
) -> tuple[np.ndarray, float]:
    """The plan's first push from the book's pose now: (2,) world hand start and yaw (rad).

    The candidate push of the book's pose nearest the plan's yaw, snapped to the
    reachability cell the planner was told.
    """
    origins, yaws = task.candidate_pushes(poses[0][None])
    nearest = int(np.argmin(np.abs(np.angle(np.exp(1j * (yaws - plan.yaws[0]))))))
    origin, snapped = reach.snap(origins[0, nearest], np.array(yaws[nearest]))
    return origin, float(snapped)


def _vetoed(
    task: EdgeTask,
    transition: Transition,
    reach: PushReachability,
    poses: np.ndarray,
    plan: EdgePlan,
    risk: bool,
) -> bool:
    """Whether the planner's own test (`push_admissible`) refuses the plan's next push now."""
    origin, yaw = _next_push(task, reach, poses, plan)
    return not push_admissible(task, transition, poses[0], poses[1], origin, yaw, risk=risk)


def _push(
    task: EdgeTask,
    sim: PushSimulator,
    reach: PushReachability,
    scene: SceneInstance,
    poses: np.ndarray,
    plan: EdgePlan,
    trajectories: bool,
) -> tuple[EdgeStep, np.ndarray] | None:
    """Execute the plan's first push (snapped to the reachability cell the planner was told).

    Returns:
        The step and the (2, 3) poses after it, or ``None`` if the exact IK refused the push.
    """
    origin, yaw = _next_push(task, reach, poses, plan)
    push = replace(
        scene,
        poses=poses.copy(),
        push_origin=origin,
        push_yaw=float(yaw),
        push_distance=task.push_distance,
    )
    try:
        sample = sim.execute([push])[0]
    except UnreachablePoseError:
        return None
    out = sample.outcome
    predicted = plan.predicted[0]
    error = float(np.hypot(*(out.state_after[0, :2] - predicted[:2])))
    fell = bool(out.fell_off[0])
    step = EdgeStep(
        yaw=float(yaw),
        origin=origin.tolist(),
        before=poses[0].tolist(),
        predicted=predicted.tolist(),
        after=out.state_after[0].tolist(),
        error=error,
        replanned=error > task.replan_distance and not fell,
        fell=fell,
        hand=out.traj_hand.tolist() if trajectories else [],
        book_path=out.traj_objects[:, 0].tolist() if trajectories else [],
    )
    return step, out.state_after.copy()


def run_edge_episode(
    task: EdgeTask,
    transition: Transition,
    seed: int,
    *,
    search: str = "astar",
    risk: bool = False,
    label: str | None = None,
    simulator: PushSimulator | None = None,
    reach: PushReachability | None = None,
    trajectories: bool = True,
    recheck: bool = True,
) -> EdgeEpisode:
    """Run one closed-loop episode (replanning and `recheck`: the module docstring).

    Args:
        task: The task.
        transition: The planner's model of the pushes.
        seed: Seeds the start, the physics and nothing else (the transition has its own).
        search: ``"astar"`` or ``"greedy"``.
        risk: The risk-aware variant (bounds on P(fall) and P(collision)).
        label: The planner's name in the record.
        simulator: The executing simulator (built from the task when ``None``).
        reach: The planner's reachability cache (built when ``None``; share it across
            episodes of one process).
        trajectories: Keep the executed hand and book trajectories in the record.
        recheck: Test each later push of a kept plan from the book's pose before it runs.

    Returns:
        The episode's record.

    Raises:
        InputError: For an unknown search, a negative seed, a `recheck` that is not a bool,
            a bad task, a `transition`, `simulator` or `reach` of the wrong kind, a start off
            the table or overlapping the battery, or a transition whose predictions are not
            finite.
    """
    seed = _check_episode(task, transition, search, seed, simulator, reach, recheck)
    planner = EDGE_SEARCHES[search]
    scene = sample_episode(task, np.random.default_rng(seed))
    task.check_start(scene.poses[0], scene.poses[1])
    sim = simulator or PushSimulator(task.scene, task.world)
    reach = reach or PushReachability(task)
    poses = scene.poses.copy()
    start = poses.copy()
    plan: EdgePlan | None = None
    plans: list[list[list[float]]] = []
    seconds: list[float] = []
    steps: list[EdgeStep] = []
    replans, unreachable, vetoes = 0, 0, 0
    outcome = "budget"
    while len(steps) < task.budget:
        if bool(task.graspable(poses[0])):
            outcome = "success"
            break
        if plan is None or len(plan) == 0:
            if plans:
                replans += 1
            left = task.budget - len(steps)
            plan = planner(task, transition, poses[0], poses[1], reach, budget=left, risk=risk)
            plans.append(plan.predicted.tolist())
            seconds.append(plan.seconds)
            if len(plan) == 0:
                outcome = "stuck"
                break
        elif recheck and _vetoed(task, transition, reach, poses, plan, risk):  # a kept plan
            vetoes, plan = vetoes + 1, None
            continue
        done = _push(task, sim, reach, scene, poses, plan, trajectories)
        if done is None:
            unreachable += 1
            if unreachable > _MAX_UNREACHABLE:
                outcome = "stuck"
                break
            plan = None  # replan from here
            continue
        unreachable = 0
        step, poses = done
        steps.append(step)
        if step.fell:
            outcome = "fell"
            break
        plan = None if step.replanned else plan.rest()
    if outcome == "budget" and bool(task.graspable(poses[0])):
        outcome = "success"
    return EdgeEpisode(
        seed=seed,
        planner=label or f"{search}{'-risk' if risk else ''}:{transition.name}",
        success=outcome == "success",
        outcome=outcome,
        pushes=len(steps),
        replans=replans,
        vetoes=vetoes,
        plans=plans,
        planning_seconds=seconds,
        start=start.tolist(),
        final=poses[0].tolist(),
        steps=steps,
    )
