"""Tool-push trials: a seeded start out of reach, a plan, its open-loop execution, a score.

A trial draws a start state whose target lies between ``min_outside`` and ``max_outside``
outside the reachable region (`draw_tool_push_episode`), plans with one of
`TOOL_PUSH_PLANNERS`: ``"two_step"`` (the thesis planner with a learned model),
``"single_step"`` (the best of ``sizes.first`` single pushes by the same criterion),
``"random"`` (two random reachable pushes, the second drawn around the tool's observed pose
after the first) and ``"two_step_sim"`` (the two-step planner with `SimulatorTransition`; each
candidate is a full physics rollout, so it samples ``sim_sizes`` (24, 4 and 12) candidates
instead of 100, 10 and 100). The plan is executed open loop, as in the thesis, by
`PushSimulator.execute` (IK and physics) in an episode whose masses, frictions and pressure
distributions are drawn once per trial and are unknown to the planner. Every trial is
deterministic given its seed.

Covered by tests/planning/tool_push/test_tool_push.py.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import numpy as np
import torch

from probaff._checks import check_count
from probaff._threads import limit_threads
from probaff.errors import ConfigError, InputError, UnreachablePoseError
from probaff.planning.learned import FeaturePushModel
from probaff.planning.tool_push.config import N_OBJECTS, ToolPushConfig, check_config
from probaff.planning.tool_push.planners import (
    ToolPushPlan,
    plan_random_push,
    plan_single_push,
    plan_tool_push,
)
from probaff.planning.tool_push.state import ToolPushState, tool_push_context
from probaff.planning.transitions import LearnedTransition, SimulatorTransition
from probaff.sim.runner import PushSimulator
from probaff.sim.sampling import sample_scene
from probaff.sim.specs import load_catalogue
from probaff.sim.tabletop import SceneInstance
from probaff.sim.tabletop_config import TabletopSpec

__all__ = [
    "TOOL_PUSH_PLANNERS",
    "ToolPushTrial",
    "draw_tool_push_episode",
    "run_tool_push_trial",
    "tool_push_scores",
]

TOOL_PUSH_PLANNERS = ("random", "single_step", "two_step", "two_step_sim")
"""Planners `run_tool_push_trial` runs, by name."""


def draw_tool_push_episode(seed: int, config: ToolPushConfig | None = None) -> SceneInstance:
    """The start state and hidden physical parameters of one trial.

    Scenes are drawn from the template (`sample_scene`: poses, masses, frictions and
    pressure distributions) until the target starts between `min_outside` and `max_outside`
    outside the reachable region and the arm can execute the drawn push of the tool.

    Args:
        seed: Trial seed (an integer >= 0); the episode depends on it alone.
        config: Task settings.

    Returns:
        The episode; its push fields are the drawn push, which no planner uses.

    Raises:
        InputError: For a bad seed.
        ConfigError: If no draw in `max_draws` qualifies.
    """
    config = check_config(config)
    seed = check_count("seed", seed, minimum=0)
    ctx = tool_push_context(config)
    rng = np.random.default_rng(np.random.SeedSequence(seed).spawn(2)[0])
    catalogue = load_catalogue()
    for _ in range(config.max_draws):
        s = sample_scene(ctx.scene, catalogue, ctx.world, rng)
        if s is None:
            continue
        depth = float(ctx.region.depth(s.poses[1, :2]))
        if not -config.max_outside <= depth <= -config.min_outside:
            continue
        ok = ctx.arm.solve_pushes(
            torch.as_tensor(s.push_origin[None]),
            torch.tensor([s.push_yaw], dtype=torch.float64),
            s.push_distance,
        ).ok
        if bool(ok[0]):
            return s
    raise ConfigError(
        f"no draw of scene {config.scene!r} in {config.max_draws} puts the target between "
        f"{config.min_outside} and {config.max_outside} m outside the reachable region with a "
        "reachable push of the tool; widen ToolPushConfig.min_outside/max_outside or move the "
        "scene's objects (worlds/scenes/tool_push.yaml)."
    )


@dataclass(frozen=True)
class ToolPushTrial:
    """One executed tool-push trial.

    Attributes:
        planner: A name from `TOOL_PUSH_PLANNERS`.
        seed: The trial seed.
        objects: Catalogue names of (tool, target).
        initial: (2, 3) world poses at the start.
        initial_depth: The target's signed distance into the region at the start (m).
        pushes: (S, 3) executed hand starts and yaws ``(x, y, yaw)``.
        predicted: (S, 2, 3) the planner's predicted poses after each push (NaN for
            ``"random"``).
        executed: (S, 2, 3) the poses after each executed push.
        final_depth: The target's final signed distance into the region (m); positive
            inside.
        reached: The target ends inside the region, on the table.
        fell_off: An object fell off the table (the trial then stops).
        refused: The arm refused a planned push at execution (the trial then stops).
        planning_time_s: Seconds spent planning (all steps).
        transition_calls: Calls to the transition model.
    """

    planner: str
    seed: int
    objects: tuple[str, str]
    initial: np.ndarray
    initial_depth: float
    pushes: np.ndarray
    predicted: np.ndarray
    executed: np.ndarray
    final_depth: float
    reached: bool
    fell_off: bool
    refused: bool
    planning_time_s: float
    transition_calls: int = 0

    def to_dict(self) -> dict[str, Any]:
        """A JSON-able record (arrays as nested lists, NaN as ``None``)."""

        def plain(x: np.ndarray) -> Any:
            return [plain(v) for v in x] if x.ndim else (None if np.isnan(x) else float(x))

        return {
            "planner": self.planner,
            "seed": self.seed,
            "objects": list(self.objects),
            "initial": plain(self.initial),
            "initial_depth": self.initial_depth,
            "pushes": plain(self.pushes),
            "predicted": plain(self.predicted),
            "executed": plain(self.executed),
            "final_depth": self.final_depth,
            "reached": self.reached,
            "fell_off": self.fell_off,
            "refused": self.refused,
            "planning_time_s": self.planning_time_s,
            "transition_calls": self.transition_calls,
        }


def _plans(
    planner: str,
    model: FeaturePushModel | None,
    state: ToolPushState,
    rng: np.random.Generator,
    config: ToolPushConfig,
) -> list[ToolPushPlan]:
    """The open-loop plan of `planner` from `state` (none yet for ``"random"``)."""
    world = tool_push_context(config).world
    if planner == "two_step":
        assert model is not None
        return [plan_tool_push(LearnedTransition(model, world), state, rng, config)]
    if planner == "single_step":
        assert model is not None
        return [plan_single_push(LearnedTransition(model, world), state, rng, config)]
    if planner == "two_step_sim":
        sim = SimulatorTransition(world)
        return [plan_tool_push(sim, state, rng, config, sizes=config.sim_sizes)]
    return []


@lru_cache(maxsize=4)
def _simulator(config: ToolPushConfig) -> PushSimulator:
    ctx = tool_push_context(config)
    return PushSimulator(ctx.scene, ctx.world)


def run_tool_push_trial(
    planner: str,
    model: FeaturePushModel | None,
    seed: int,
    config: ToolPushConfig | None = None,
) -> ToolPushTrial:
    """Draw an episode, plan with `planner`, execute with the arm and physics, score it.

    The plan is executed open loop (as in the thesis): each push runs from its planned hand
    start, whatever the previous push really did; ``"random"`` draws its second push around
    the tool's observed pose. Torch runs single-threaded during the trial.

    Args:
        planner: A name from `TOOL_PUSH_PLANNERS`.
        model: The learned chapter-5 model (``"two_step"``, ``"single_step"``); ignored by
            the others and may be ``None`` for them.
        seed: Trial seed (an integer >= 0): the same seed gives every planner the same
            episode, and the same planner the same trial.
        config: Task settings.

    Returns:
        The trial.

    Raises:
        InputError: For an unknown planner, a missing or mismatched model, or a bad seed.
    """
    if not isinstance(planner, str) or planner not in TOOL_PUSH_PLANNERS:
        raise InputError(f"unknown planner {planner!r}; choose one of {TOOL_PUSH_PLANNERS}.")
    config = check_config(config)
    if planner in ("two_step", "single_step") and not isinstance(model, FeaturePushModel):
        raise InputError(
            f"planner {planner!r} needs a fitted chapter-5 model as a FeaturePushModel "
            f"(fit_tool_push_model), got {type(model).__name__}."
        )
    seed = check_count("seed", seed, minimum=0)
    ctx = tool_push_context(config)
    with limit_threads(1):
        episode = draw_tool_push_episode(seed, config)
        state = ToolPushState(episode.objects, episode.poses)
        rng = np.random.default_rng(np.random.SeedSequence(seed).spawn(2)[1])
        plans = _plans(planner, model, state, rng, config)
        sim = _simulator(config)
        poses, executed, pushes, predicted = episode.poses, [], [], []
        fell = refused = False
        for step in range(2 if planner == "random" else len(plans[0].push_yaw)):
            if planner == "random":
                try:
                    plans.append(
                        plan_random_push(ToolPushState(episode.objects, poses), rng, config)
                    )
                except (UnreachablePoseError, InputError):
                    break  # the tool left the arm's reach, or the boxes overlap after push 1
                plan, k = plans[-1], 0
            else:
                plan, k = plans[0], step
            push = dataclasses.replace(
                episode, poses=poses, push_origin=plan.push_origin[k], push_yaw=plan.push_yaw[k]
            )
            try:
                outcome = sim.execute([push])[0].outcome
            except UnreachablePoseError:
                refused = True  # IK of the lone push failed where the planner's batch passed
                break
            poses = outcome.state_after
            executed.append(poses)
            pushes.append([*plan.push_origin[k], plan.push_yaw[k]])
            predicted.append(plan.predicted[k])
            if outcome.fell_off.any():
                fell = True
                break
    final_depth = float(ctx.region.depth(poses[1, :2]))
    return ToolPushTrial(
        planner=planner,
        seed=seed,
        objects=(episode.objects[0].name, episode.objects[1].name),
        initial=np.array(episode.poses),
        initial_depth=float(ctx.region.depth(episode.poses[1, :2])),
        pushes=np.array(pushes, dtype=float).reshape(-1, 3),
        predicted=np.array(predicted, dtype=float).reshape(-1, N_OBJECTS, 3),
        executed=np.array(executed, dtype=float).reshape(-1, N_OBJECTS, 3),
        final_depth=final_depth,
        reached=bool(final_depth > 0 and not _off_table(poses[1], ctx.world)),
        fell_off=fell,
        refused=refused,
        planning_time_s=float(sum(p.planning_time_s for p in plans)),
        transition_calls=int(sum(p.transition_calls for p in plans)),
    )


def _off_table(pose: np.ndarray, world: TabletopSpec) -> bool:
    return bool(
        abs(pose[0]) > 0.5 * world.table_size[0] or abs(pose[1]) > 0.5 * world.table_size[1]
    )


def tool_push_scores(trials: Sequence[ToolPushTrial]) -> dict[str, dict[str, float]]:
    """Per planner: trials, success fraction, mean final depth and planning time.

    Args:
        trials: Trials of any planners.

    Returns:
        planner -> ``{"trials", "success", "mean_depth", "std_depth", "mean_planning_time_s"}``
        (success: the fraction whose target ends inside the region; depth in metres).

    Raises:
        InputError: If `trials` is empty or holds something other than `ToolPushTrial`.
    """
    trials = list(trials)
    if not trials or not all(isinstance(t, ToolPushTrial) for t in trials):
        raise InputError("trials must be a non-empty list of ToolPushTrial.")
    out: dict[str, dict[str, float]] = {}
    for name in sorted({t.planner for t in trials}):
        ts = [t for t in trials if t.planner == name]
        depth = np.array([t.final_depth for t in ts])
        out[name] = {
            "trials": float(len(ts)),
            "success": float(np.mean([t.reached for t in ts])),
            "mean_depth": float(depth.mean()),
            "std_depth": float(depth.std(ddof=1)) if len(ts) > 1 else 0.0,
            "mean_planning_time_s": float(np.mean([t.planning_time_s for t in ts])),
        }
    return out
