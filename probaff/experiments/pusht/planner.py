"""Closed-loop push planning on Push-T: beam search over push primitives, and its episodes.

What is scored is apart from how it is searched. A transition (`ModelTransition` over a learned
or analytic push model, `EnvTransition` over a copy of the environment itself) predicts where
each candidate primitive leaves the block; `plan_push` searches: it samples
`SearchSettings.candidates` feasible first pushes, keeps the `SearchSettings.beam` best, samples
`SearchSettings.children` second pushes after each, and returns the first push of the best
sequence (`SearchSettings.depth` 1 is the greedy one-push planner). A sequence scores by the
mean distance of the T's vertices from the goal's (`keypoint_cost`) where it ends, plus a small
price per control step; the risk-aware variant adds `SearchSettings.risk` times the predictive
standard deviation of the first push's outcome, in the same units.

`run_episode` is one closed-loop episode in the unmodified environment: observe, plan, run the
primitive's targets, observe again, until the environment's own rule ends it (coverage > 95 %)
or its own 300-step limit does.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from probaff._checks import check_count, check_positive
from probaff.errors import InputError
from probaff.experiments.pusht.env import PushTWorker
from probaff.experiments.pusht.geometry import (
    AGENT_RADIUS,
    ARENA,
    KEYPOINTS,
    cog_pose,
    distance_to_tee,
    keypoint_cost,
    origin_pose,
    to_world,
)
from probaff.experiments.pusht.models import predict_moments
from probaff.experiments.pusht.observe import observer
from probaff.experiments.pusht.primitives import (
    PrimitiveSettings,
    primitive_actions,
    push_frames,
    sample_primitives,
)

__all__ = [
    "EnvTransition",
    "ModelTransition",
    "Node",
    "SearchSettings",
    "Transition",
    "plan_push",
    "run_episode",
]

_RADIUS = float(np.sqrt((KEYPOINTS**2).sum(axis=1).mean()))  # RMS vertex radius (px)


@dataclass(frozen=True)
class SearchSettings:
    """The search's budget and scoring.

    Attributes:
        candidates: First pushes sampled per planning step.
        beam: First pushes whose children are expanded (depth 2).
        children: Second pushes sampled after each kept first push.
        depth: 1 (greedy one push) or 2.
        risk: Weight of the first push's predictive standard deviation (0: mean only).
        step_cost: Price of a control step, in px of vertex distance.
    """

    candidates: int = 192
    beam: int = 8
    children: int = 48
    depth: int = 2
    risk: float = 0.0
    step_cost: float = 0.02

    def __post_init__(self) -> None:
        for name in ("candidates", "beam", "children"):
            check_count(f"SearchSettings.{name}", getattr(self, name))
        check_count("SearchSettings.depth", self.depth)
        if self.depth > 2:
            raise InputError(f"SearchSettings.depth must be 1 or 2, got {self.depth}.")
        check_positive("SearchSettings.risk", self.risk, allow_zero=True)
        check_positive("SearchSettings.step_cost", self.step_cost, allow_zero=True)


@dataclass(frozen=True)
class Node:
    """A state the search reaches: the block's pose and the agent's position and velocity."""

    pose: np.ndarray
    agent: np.ndarray
    agent_vel: np.ndarray


class Transition(Protocol):
    """Where primitives leave the block: children nodes and their outcomes' spread."""

    def expand(
        self, node: Node, prims: np.ndarray, settings: PrimitiveSettings
    ) -> tuple[list[Node], np.ndarray]:
        """Children of `node` for (K, 3) primitives, and (K,) outcome std (px)."""
        ...


def _step_estimate(node: Node, prims: np.ndarray, s: PrimitiveSettings) -> np.ndarray:
    """Rough control steps of each primitive: the straight way to its start, then the push."""
    start = to_world(node.pose, push_frames(prims, s)["start"])
    travel = np.linalg.norm(start - node.agent, axis=-1) * 1.3
    return travel / s.approach_speed + (s.gap + prims[:, 2]) / s.push_speed + s.wait + s.settle


@dataclass
class ModelTransition:
    """Children predicted by a push model (its predictive mean; std for the risk term).

    Attributes:
        model: A `LearnedModel` or a calibrated `QuasiStaticTee`.
    """

    model: Any

    def expand(
        self, node: Node, prims: np.ndarray, settings: PrimitiveSettings
    ) -> tuple[list[Node], np.ndarray]:
        """Predicted children of `node` and the std (px) of each outcome."""
        geo = push_frames(prims, settings)
        travel = settings.gap + prims[:, 2]
        X = np.column_stack([geo["start"], geo["direction"], travel])
        mean, std = predict_moments(self.model, X)
        yaw = node.pose[2] + geo["yaw"]
        c, s = np.cos(yaw), np.sin(yaw)
        dx = c * mean[:, 1] - s * mean[:, 0]
        dy = s * mean[:, 1] + c * mean[:, 0]
        poses = np.column_stack([node.pose[0] + dx, node.pose[1] + dy, node.pose[2] + mean[:, 2]])
        ends = to_world(node.pose, geo["start"] + geo["direction"] * travel[:, None])
        spread = np.sqrt(std[:, 0] ** 2 + std[:, 1] ** 2 + (_RADIUS * std[:, 2]) ** 2)
        zero = np.zeros(2)
        return [Node(p, e, zero) for p, e in zip(poses, ends, strict=True)], spread


@dataclass
class EnvTransition:
    """Children simulated by a second instance of the environment (the upper bound).

    Attributes:
        worker: The Push-T worker whose model environment runs the rollouts.
    """

    worker: PushTWorker

    def expand(
        self, node: Node, prims: np.ndarray, settings: PrimitiveSettings
    ) -> tuple[list[Node], np.ndarray]:
        """Simulated children of `node` (zero spread)."""
        seqs = [
            primitive_actions(node.pose, node.agent, p, settings).actions.tolist() for p in prims
        ]
        state = {
            "agent": node.agent.tolist(),
            "agent_vel": node.agent_vel.tolist(),
            "block": origin_pose(node.pose).tolist(),
        }
        results = self.worker.ask("rollout", state=state, sequences=seqs)["results"]
        nodes = [
            Node(cog_pose(np.array(r["block"])), np.array(r["agent"]), np.array(r["agent_vel"]))
            for r in results
        ]
        return nodes, np.zeros(len(nodes))


def _feasible(pose: np.ndarray, prims: np.ndarray, s: PrimitiveSettings) -> np.ndarray:
    """(K,) whether each push starts clear of the T and inside the arena."""
    start = push_frames(prims, s)["start"]
    d, _ = distance_to_tee(start)
    world = to_world(pose, start)
    inside = np.all((world >= ARENA[0]) & (world <= ARENA[1]), axis=-1)
    return (d >= AGENT_RADIUS + s.gap - 1e-6) & inside


def _sample(rng: np.random.Generator, pose: np.ndarray, n: int, s: PrimitiveSettings) -> np.ndarray:
    """`n` feasible primitives at `pose` (fewer if few are feasible)."""
    prims = sample_primitives(rng, 3 * n, s)
    return prims[_feasible(pose, prims, s)][:n]


def plan_push(
    node: Node,
    goal: np.ndarray,
    transition: Transition,
    rng: np.random.Generator,
    search: SearchSettings,
    prims: PrimitiveSettings,
) -> tuple[np.ndarray, np.ndarray, float]:
    """The first push of the best sequence found.

    Args:
        node: The observed state.
        goal: (3,) the goal's centre-of-gravity pose.
        transition: What predicts a push's outcome.
        rng: The search's random generator.
        search: Budget and scoring.
        prims: The primitives' settings.

    Returns:
        ``(primitive (3,), its predicted pose (3,), the sequence's score)``.
    """
    first = _sample(rng, node.pose, search.candidates, prims)
    if len(first) == 0:
        first = sample_primitives(rng, 1, prims)
    kids, spread = transition.expand(node, first, prims)
    steps = _step_estimate(node, first, prims)
    cost = np.array([float(keypoint_cost(k.pose, goal)) for k in kids])
    score = cost + search.risk * spread + search.step_cost * steps
    if search.depth == 2:
        for i in np.argsort(score)[: search.beam]:
            second = _sample(rng, kids[i].pose, search.children, prims)
            if len(second) == 0:
                continue
            grand, _ = transition.expand(kids[i], second, prims)
            steps2 = _step_estimate(kids[i], second, prims)
            cost2 = np.array([float(keypoint_cost(g.pose, goal)) for g in grand])
            best = float(np.min(cost2 + search.step_cost * steps2))
            extra = search.risk * spread[i] + search.step_cost * steps[i]
            score[i] = min(score[i], best + extra)
    j = int(np.argmin(score))
    return first[j], kids[j].pose, float(score[j])


def run_episode(
    worker: PushTWorker,
    seed: int,
    transition: Transition | None,
    search: SearchSettings,
    prims: PrimitiveSettings,
    *,
    trajectory: bool = False,
    observation: str = "state",
) -> dict[str, Any]:
    """One closed-loop episode in the environment, from its reset with `seed`.

    Args:
        worker: The Push-T worker (its episode environment).
        seed: The environment's reset seed (and the search's).
        transition: The planner's transition; None pushes at random.
        search: The search's settings.
        prims: The primitives' settings.
        trajectory: Keep the block's pose after every push.
        observation: What the planner observes (`probaff.experiments.pusht.observe`):
            ``"state"``, the environment's state; or ``"pixels"``, only the diffusion
            policy's observation (the 96 x 96 image and the agent's position), from which the
            goal and the block's pose are perceived. The state is then used for scoring only.

    Returns:
        ``success`` (the environment terminated: coverage > 95 %), ``max_coverage``,
        ``final_coverage``, ``pushes``, ``steps``, ``plan_seconds`` (mean per push),
        ``error_px`` (mean distance of the executed from the predicted pose's vertices), and
        ``poses`` (the state's centre-of-gravity poses, px) when `trajectory`. With
        ``observation="pixels"`` also ``observation``, ``flagged`` (frames not read),
        ``retreats`` (times the pusher backed away), ``perception_px`` and ``perception_deg``
        (mean error of the perceived poses planned on, px of the image and degrees) and
        ``lost`` (the block could not be read even after backing away; the episode ends).

    Raises:
        InputError: For an unknown `observation`.
    """
    eye = observer(observation, worker)
    seen = eye.reset(int(seed))
    goal = eye.goal
    rng = np.random.default_rng(np.random.SeedSequence(int(seed), spawn_key=(7,)))
    coverage = list(seen.coverage)
    poses = [seen.truth]
    plan_s: list[float] = []
    errors: list[float] = []
    done, success, lost = seen.terminated or seen.truncated, seen.terminated, seen.lost
    steps = seen.steps
    while not done and not lost:
        node = Node(seen.pose, seen.agent, seen.agent_vel)
        t0 = time.perf_counter()
        if transition is None:
            prim = _sample(rng, node.pose, 1, prims)
            prim = prim[0] if len(prim) else sample_primitives(rng, 1, prims)[0]
            predicted = None
        else:
            prim, predicted, _ = plan_push(node, goal, transition, rng, search, prims)
        plan_s.append(time.perf_counter() - t0)
        actions = primitive_actions(node.pose, node.agent, prim, prims).actions
        seen = eye.step(actions)
        coverage += seen.coverage
        poses.append(seen.truth)
        if predicted is not None:
            errors.append(float(keypoint_cost(poses[-1], predicted)))
        steps = seen.steps
        success = seen.terminated
        done = success or seen.truncated
        lost = seen.lost
    record: dict[str, Any] = {
        "seed": int(seed),
        "success": success,
        "max_coverage": float(max(coverage)),
        "final_coverage": float(coverage[-1]),
        "pushes": len(plan_s),
        "steps": steps,
        "plan_seconds": float(np.mean(plan_s)) if plan_s else math.nan,
        "error_px": float(np.mean(errors)) if errors else math.nan,
    }
    if observation != "state":
        record |= {**eye.record(), "lost": bool(lost and not done)}
    if trajectory:
        record["poses"] = np.array(poses).round(3).tolist()
    return record
