"""Closed-loop push planning on Push-T: beam search over push primitives, and its episodes.

What is scored is apart from how it is searched, on probaff's one planning stack. A
`probaff.planning.transitions.Transition` over Push-T's pushes
(`probaff.experiments.pusht.transitions`: `ModelTransition` over a learned or analytic push
model, `EnvTransition` over a copy of the environment itself) predicts where each candidate
primitive leaves the block; `TeeSearch` poses Push-T as a
`probaff.planning.search.SamplingProblem`, and `plan_push` runs `probaff.planning.search`'s
sampling searches on it: `sample_two_steps` samples `SearchSettings.candidates` feasible first
pushes, keeps the `SearchSettings.beam` best, samples `SearchSettings.children` second pushes
after each, and the first push of the best sequence is returned (`SearchSettings.depth` 1 is
`sample_best`, the greedy one-push planner). A sequence scores by the mean distance of the T's
vertices from the goal's (`keypoint_cost`) where it ends, plus a small price per control step;
the risk-aware variant adds `SearchSettings.risk` times the predictive standard deviation of
the first push's outcome, in the same units.

`run_episode` is one closed-loop episode in the unmodified environment: observe, plan, run the
primitive's targets, observe again, until the environment's own rule ends it (coverage > 95 %)
or its own 300-step limit does.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from probaff._checks import check_count, check_positive
from probaff.errors import InputError
from probaff.experiments.pusht.env import PushTWorker
from probaff.experiments.pusht.geometry import (
    GYM_TEE,
    TeeGeometry,
    cog_pose,
    keypoint_cost,
    origin_pose,
    to_world,
)
from probaff.experiments.pusht.models import check_model_observation
from probaff.experiments.pusht.observe import FRAMES_KEPT, observer
from probaff.experiments.pusht.primitives import (
    PrimitiveSettings,
    feasible_starts,
    primitive_actions,
    push_frames,
    sample_primitives,
)
from probaff.experiments.pusht.transitions import TeePushes
from probaff.planning.search import sample_best, sample_two_steps
from probaff.planning.transitions import Transition, check_transition, checked_prediction

__all__ = [
    "Node",
    "SearchSettings",
    "TeeCandidates",
    "TeeSearch",
    "plan_push",
    "run_episode",
]


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


def _step_estimate(
    node: Node, prims: np.ndarray, s: PrimitiveSettings, tee: TeeGeometry
) -> np.ndarray:
    """Rough control steps of each primitive: the straight way to its start, then the push."""
    start = to_world(node.pose, push_frames(prims, s, tee)["start"])
    travel = np.linalg.norm(start - node.agent, axis=-1) * 1.3
    return travel / s.approach_speed + (s.gap + prims[:, 2]) / s.push_speed + s.wait + s.settle


def _sample(
    rng: np.random.Generator, pose: np.ndarray, n: int, s: PrimitiveSettings, tee: TeeGeometry
) -> np.ndarray:
    """`n` feasible primitives at `pose` (fewer if few are feasible)."""
    prims = sample_primitives(rng, 3 * n, s, tee)
    return prims[feasible_starts(pose, prims, s, tee)][:n]


# A search state, (D,) floats: the T's pose, the agent's position and velocity, the score of
# the sequence that reaches it (lower is better), the price already paid on the way beyond the
# vertex cost (risk and steps of the first push), and its depth (0: the observed state).
_POSE, _AGENT, _VEL, _SCORE, _EXTRA, _DEPTH = (
    slice(0, 3),
    slice(3, 5),
    slice(5, 7),
    7,
    8,
    9,
)
_WIDTH = 10


def _state(node: Node) -> np.ndarray:
    """(D,) the search state of an observed node."""
    out = np.zeros(_WIDTH)
    out[_POSE], out[_AGENT], out[_VEL] = node.pose, node.agent, node.agent_vel
    return out


def _node(state: np.ndarray) -> Node:
    return Node(state[_POSE].copy(), state[_AGENT].copy(), state[_VEL].copy())


@dataclass(frozen=True)
class TeeCandidates:
    """Primitives sampled from several search states (`probaff.planning.search.Candidates`).

    Attributes:
        prims: (C, 3) primitives ``(s, phi, length)``; a row of NaN where `stay`.
        state: (C,) index of the state each acts from.
        stay: (C,) the sequence ends before this step (a state from which no feasible
            primitive was found keeps its one-push score).
    """

    prims: np.ndarray
    state: np.ndarray
    stay: np.ndarray

    def __len__(self) -> int:
        return len(self.prims)


class TeeSearch:
    """Push-T as a `probaff.planning.search.SamplingProblem` over (D,) search states.

    A sequence scores by the mean distance of the T's vertices from the goal's where it ends
    (`keypoint_cost`), plus `SearchSettings.step_cost` per estimated control step of each
    push, plus `SearchSettings.risk` times the first push's predictive spread (px): the root
    mean square of its effect's standard deviations, the turn's as the arc of the T's RMS
    vertex radius. A two-push sequence scores no worse than its first push alone (the search
    may stop after one). The transition is asked once per state expanded.

    Args:
        transition: Predicts where primitives leave the T (``Transition[TeePushes]``).
        goal: (3,) the goal's centre-of-gravity pose.
        rng: The search's random generator (the candidates).
        search: Budget and scoring.
        prims: The primitives' settings.
        tee: The T pushed (gym-pusht's, or the one perceived from the images).
    """

    def __init__(
        self,
        transition: Transition[TeePushes],
        goal: np.ndarray,
        rng: np.random.Generator,
        search: SearchSettings,
        prims: PrimitiveSettings,
        tee: TeeGeometry = GYM_TEE,
    ) -> None:
        self.transition, self.goal, self.rng = transition, goal, rng
        self.search, self.prims, self.tee = search, prims, tee

    def sample(self, states: np.ndarray, n: int, allow_empty: bool) -> TeeCandidates:
        """Up to `n` feasible primitives from one (D,) state or each of (S, D) states.

        From one state with none feasible, one primitive drawn at random; from several (with
        `allow_empty`), a state with none feasible gets one `stay` candidate.
        """
        rows = np.atleast_2d(states)
        prims, index, stay = [], [], []
        for i, state in enumerate(rows):
            found = _sample(self.rng, state[_POSE], n, self.prims, self.tee)
            if len(found) == 0 and not allow_empty:
                found = sample_primitives(self.rng, 1, self.prims, self.tee)
            if len(found) == 0:
                found, ends = np.full((1, 3), np.nan), [True]
            else:
                ends = [False] * len(found)
            prims.append(found)
            index += [i] * len(found)
            stay += ends
        return TeeCandidates(np.concatenate(prims), np.array(index), np.array(stay))

    def predict(self, states: np.ndarray, candidates: TeeCandidates) -> np.ndarray:
        """(C, D) the search state after each candidate from its (C, D) state."""
        out = np.array(states, dtype=float, copy=True)
        cut = np.flatnonzero(np.diff(candidates.state)) + 1
        for rows in np.split(np.arange(len(candidates)), cut):
            parent = states[rows[0]]
            go = rows[~candidates.stay[rows]]
            if len(go):  # otherwise the sequence ends at the parent, with its score
                out[go] = self._children(parent, candidates.prims[go])
            out[rows, _DEPTH] = parent[_DEPTH] + 1
        return out

    def _children(self, parent: np.ndarray, prims: np.ndarray) -> np.ndarray:
        """(K, D) the states after (K, 3) primitives from one (D,) state, scored."""
        node, s = _node(parent), self.search
        k = len(prims)
        pushes = TeePushes(
            np.repeat(node.pose[None], k, 0),
            np.repeat(node.agent[None], k, 0),
            np.repeat(node.agent_vel[None], k, 0),
            prims,
            self.prims,
            self.tee,
        )
        pred = checked_prediction(self.transition, self.transition.predict(pushes), (k, 1))
        if pred.pusher is None or pred.effect_std is None:
            raise InputError(
                f"the Push-T transition {self.transition.name!r} must predict the agent's state "
                "(pusher) and the effects' standard deviation (effect_std); use "
                "ModelTransition or EnvTransition."
            )
        poses = pred.mean[:, 0]
        std = pred.effect_std[:, 0]
        steps = _step_estimate(node, prims, self.prims, self.tee)
        cost = np.array([float(keypoint_cost(p, self.goal, self.tee)) for p in poses])
        out = np.zeros((k, _WIDTH))
        out[:, _POSE], out[:, _AGENT], out[:, _VEL] = poses, pred.pusher[:, :2], pred.pusher[:, 2:]
        if parent[_DEPTH] == 0:
            radius = self.tee.radius
            spread = np.sqrt(std[:, 0] ** 2 + std[:, 1] ** 2 + (radius * std[:, 2]) ** 2)
            out[:, _SCORE] = cost + s.risk * spread + s.step_cost * steps
            out[:, _EXTRA] = s.risk * spread + s.step_cost * steps
        else:
            later = (cost + s.step_cost * steps) + parent[_EXTRA]
            out[:, _SCORE] = np.minimum(parent[_SCORE], later)
            out[:, _EXTRA] = parent[_EXTRA] + s.step_cost * steps
        return out

    def rank(self, states: np.ndarray) -> np.ndarray:
        """(n,) the one-push scores: the lowest first pushes are kept."""
        return states[:, _SCORE]

    def score(self, states: np.ndarray) -> np.ndarray:
        """(n,) minus the sequences' scores (the search takes the highest)."""
        return -states[:, _SCORE]


def plan_push(
    node: Node,
    goal: np.ndarray,
    transition: Transition[TeePushes],
    rng: np.random.Generator,
    search: SearchSettings,
    prims: PrimitiveSettings,
    tee: TeeGeometry = GYM_TEE,
) -> tuple[np.ndarray, np.ndarray, float]:
    """The first push of the best sequence found, by `probaff.planning.search`.

    Depth 1 is `sample_best` over `SearchSettings.candidates` first pushes; depth 2 is
    `sample_two_steps`: it keeps the `SearchSettings.beam` best first pushes and samples
    `SearchSettings.children` second pushes after each (`TeeSearch` scores them).

    Args:
        node: The observed state.
        goal: (3,) the goal's centre-of-gravity pose.
        transition: What predicts a push's outcome (``Transition[TeePushes]``).
        rng: The search's random generator.
        search: Budget and scoring.
        prims: The primitives' settings.
        tee: The T pushed (its outline, centre of gravity and, for the analytic model, inertia).

    Returns:
        ``(primitive (3,), its predicted pose (3,), the sequence's score)``.
    """
    problem = TeeSearch(check_transition(transition), goal, rng, search, prims, tee)
    root = _state(node)
    if search.depth == 1:
        plan = sample_best(problem, root, search.candidates)
    else:
        plan = sample_two_steps(problem, root, search.candidates, search.beam, search.children)
    j = plan.chosen[0]
    return plan.candidates[0].prims[j], plan.predicted[0, _POSE].copy(), -plan.score


def run_episode(
    worker: PushTWorker,
    seed: int,
    transition: Transition[TeePushes] | None,
    search: SearchSettings,
    prims: PrimitiveSettings,
    *,
    trajectory: bool = False,
    observation: str = "state",
    allow_observation_mismatch: bool = False,
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
        allow_observation_mismatch: Plan with a model fitted on pushes recorded from the other
            observation (`probaff.experiments.pusht.models.check_model_observation`).

    Returns:
        ``success`` (the environment terminated: coverage > 95 %), ``max_coverage``,
        ``final_coverage``, ``pushes``, ``steps``, ``plan_seconds`` (mean per push),
        ``error_px`` (mean distance of the executed from the predicted pose's vertices), and
        ``poses`` (the state's centre-of-gravity poses, px) when `trajectory`. With
        ``observation="pixels"`` also ``observation``, ``flagged`` (frames not read),
        ``retreats`` (times the pusher backed away), ``perception_px`` and ``perception_deg``
        (mean error of the perceived poses planned on, px of the image and degrees) and
        ``lost`` (the block could not be read even after backing away; the episode ends);
        with `trajectory` also ``frames`` (`FRAMES_KEPT` images planned on, each with its
        perceived and its true body-origin pose) and ``shape`` (the perceived T's lengths).

    Raises:
        InputError: For an unknown `observation`.
        ObservationMismatchError: If `transition`'s model was fitted on pushes recorded from
            another observation than `observation` and not `allow_observation_mismatch`.
    """
    eye = observer(observation, worker, keep_frames=FRAMES_KEPT if trajectory else 0)
    check_model_observation(transition, observation, allow=allow_observation_mismatch)
    seen = eye.reset(int(seed))
    goal, tee = eye.goal, eye.tee
    rng = np.random.default_rng(np.random.SeedSequence(int(seed), spawn_key=(7,)))
    coverage = list(seen.coverage)
    poses = [seen.truth]
    plan_s: list[float] = []
    errors: list[float] = []
    done, success, lost = seen.terminated or seen.truncated, seen.terminated, seen.lost
    steps = seen.steps
    while not done and not lost:
        goal, tee = eye.goal, eye.tee  # the observer may refine the perceived scene
        node = Node(seen.pose, seen.agent, seen.agent_vel)
        t0 = time.perf_counter()
        if transition is None:
            prim = _sample(rng, node.pose, 1, prims, tee)
            prim = prim[0] if len(prim) else sample_primitives(rng, 1, prims, tee)[0]
            predicted = None
        else:
            prim, predicted, _ = plan_push(node, goal, transition, rng, search, prims, tee)
            if tee is not GYM_TEE:  # scored where the state is: gym-pusht's frame
                predicted = cog_pose(origin_pose(predicted, tee))
        plan_s.append(time.perf_counter() - t0)
        actions = primitive_actions(node.pose, node.agent, prim, prims, tee).actions
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
