"""The tool push's planners: the thesis's two steps, the best single push, a random push.

The thesis's planner (Section 5.5.4, Figure 5.7), by `probaff.planning.search
.sample_two_steps`:

1. samples ``sizes.first`` (100) pushes of the tool and keeps the ``sizes.keep`` (10) that
   leave the two boxes closest (centre to centre, predicted);
2. samples ``sizes.second`` (100) more pushes of the tool from each kept predicted state;
3. takes the two-push sequence whose predicted final state puts the target furthest into the
   reachable region.

Every candidate's effect is predicted in one batched call per step (``first`` queries, then
``keep * second``) by a `probaff.planning.transitions.Transition` whose two objects are the
tool (pushed) and the target: `LearnedTransition` (a fitted chapter-5 mixture predicting both
objects' pushing-frame effects) or `SimulatorTransition` (the oracle baseline). A learned
model's prediction is its predictive mean, which blends its experts where the gate is unsure
(e.g. whether the tool will hit the target).

Unreachable goals. Two pushes move the target at most 2 d_p, so the planners refuse a state
whose target lies further than that outside the region (`InputError`).

Covered by tests/planning/tool_push/test_tool_push.py.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from probaff.errors import InputError
from probaff.planning._checks import check_instance, check_rng
from probaff.planning.search import SampledPlan, SearchPlanner, sample_best, sample_two_steps
from probaff.planning.tool_push.candidates import ToolPushCandidates, sample_tool_pushes
from probaff.planning.tool_push.config import N_OBJECTS, SampleSizes, ToolPushConfig, check_config
from probaff.planning.tool_push.state import (
    ToolPushContext,
    ToolPushState,
    check_state,
    tool_push_context,
)
from probaff.planning.transitions import (
    PushBatch,
    Transition,
    check_moves,
    check_transition,
    checked_prediction,
)

__all__ = [
    "ToolPushPlan",
    "ToolPushPlanner",
    "plan_random_push",
    "plan_single_push",
    "plan_tool_push",
]


@dataclass(frozen=True)
class ToolPushPlan:
    """A planned push sequence.

    Attributes:
        push_origin: (S, 2) world hand starts, in order (S = 1 or 2).
        push_yaw: (S,) world yaws of z_p.
        predicted: (S, 2, 3) predicted world poses of (tool, target) after each push.
        predicted_depth: Predicted final signed distance of the target into the region (m).
        planning_time_s: Wall-clock seconds spent planning.
        transition_calls: Calls to the transition model (one per step).
        n_candidates: Candidates evaluated at each step.
    """

    push_origin: np.ndarray
    push_yaw: np.ndarray
    predicted: np.ndarray
    predicted_depth: float
    planning_time_s: float
    transition_calls: int
    n_candidates: tuple[int, ...]


class _ToolPushSampling:
    """The tool push as a `SamplingProblem` over (2, 3) poses of the tool and the target."""

    def __init__(
        self,
        transition: Transition,
        state: ToolPushState,
        rng: np.random.Generator,
        config: ToolPushConfig,
        ctx: ToolPushContext,
    ) -> None:
        self.transition, self.objects, self.rng = transition, state.objects, rng
        self.config, self.ctx = config, ctx

    def sample(self, states: np.ndarray, n: int, allow_empty: bool) -> ToolPushCandidates:
        """`sample_tool_pushes` from one state (2, 3) or several (S, 2, 3)."""
        return sample_tool_pushes(
            self.objects, states, n, self.rng, self.config, allow_empty=allow_empty
        )

    def predict(self, states: np.ndarray, candidates: ToolPushCandidates) -> np.ndarray:
        """(C, 2, 3) poses after each candidate from its (C, 2, 3) poses, in one call."""
        pushes = PushBatch(
            self.objects, states, candidates.origin, candidates.yaw, self.ctx.scene.push.distance
        )
        pred = self.transition.predict(pushes, rng=self.rng)
        return checked_prediction(self.transition, pred, states.shape[:2]).mean

    def rank(self, states: np.ndarray) -> np.ndarray:
        """The distance between the two boxes' centres (m): the closest are kept."""
        return np.linalg.norm(states[:, 0, :2] - states[:, 1, :2], axis=-1)

    def score(self, states: np.ndarray) -> np.ndarray:
        """The target's signed distance into the reachable region (m)."""
        return self.ctx.region.depth(states[:, 1, :2])


Search = Callable[[_ToolPushSampling, np.ndarray, SampleSizes], SampledPlan[ToolPushCandidates]]
"""``search(problem, poses, sizes)``: a sampling search of `probaff.planning.search`."""


class ToolPushPlanner(SearchPlanner[Search]):
    """A tool-push planner: a sampling search over the (2, 3) poses of the tool and the target.

    The planners are `plan_tool_push` and `plan_single_push`; a call checks its arguments and
    runs the search, predicting the candidates of each step in one call of the transition.

    Example:
        Plan two pushes of the tool that bring the target into the receiving arm's reach,
        with the simulator as the transition (`probaff.planning.SimulatorTransition`, the
        oracle; ``LearnedTransition(fit_tool_push_model(ds), world)`` gives the thesis's
        learned planner) and fewer candidates than the thesis's 100, 10, 100;
        `run_tool_push_trial` executes a plan with the arm and scores it:

        >>> import numpy as np
        >>> from probaff.planning import SimulatorTransition, ToolPushState, plan_tool_push
        >>> from probaff.planning.tool_push import SampleSizes, draw_tool_push_episode
        >>> from probaff.sim import load_tabletop
        >>> episode = draw_tool_push_episode(seed=0)
        >>> [o.name for o in episode.objects]  # the tool, then the target
        ['cracker_box', 'phone_box']
        >>> state = ToolPushState(episode.objects, episode.poses)  # world (x, y, theta) each
        >>> sizes = SampleSizes(first=8, keep=2, second=8)
        >>> transition = SimulatorTransition(load_tabletop())
        >>> plan = plan_tool_push(transition, state, np.random.default_rng(0), sizes=sizes)
        >>> plan.push_origin.shape, plan.predicted.shape  # (pushes, x y), (pushes, objects, pose)
        ((2, 2), (2, 2, 3))
        >>> plan.n_candidates, plan.transition_calls  # 8 first pushes, 8 from each of 2 kept
        ((8, 16), 2)
    """

    def __call__(
        self,
        transition: Transition,
        state: ToolPushState,
        rng: np.random.Generator,
        config: ToolPushConfig | None = None,
        *,
        sizes: SampleSizes | None = None,
    ) -> ToolPushPlan:
        """Plan pushes of the tool from `state`.

        Args:
            transition: Predicts the poses after candidate pushes (one call per step).
            state: The start state.
            rng: Source of randomness (candidates, sensed clouds).
            config: Task settings.
            sizes: Pushes sampled and kept; the config's `sizes` by default.

        Returns:
            The pushes, with their predictions.

        Raises:
            InputError: For a bad transition (one whose model predicts the effects of the
                tool alone included), state, generator, config or sizes, or a target that two
                pushes cannot bring within reach.
            UnreachablePoseError: If the arm can push the tool in no sampled direction.
        """
        config = check_config(config)
        ctx = tool_push_context(config)
        check_transition(transition)
        check_moves(
            transition,
            N_OBJECTS,
            "the tool push task (the tool and the target)",
            "Give a model of both objects' effects (fit_tool_push_model), not one of the "
            "pushed object's alone (such as the push-to-edge model, fit_edge_model).",
        )
        check_state(state, ctx)
        check_rng(rng)
        if sizes is None:
            sizes = config.sizes
        check_instance(sizes, SampleSizes, "sizes must be a SampleSizes(first, keep, second)")
        start = time.perf_counter()
        found = self.search(
            _ToolPushSampling(transition, state, rng, config, ctx), state.poses, sizes
        )
        steps = list(zip(found.candidates, found.chosen, strict=True))
        return ToolPushPlan(
            np.stack([c.origin[j] for c, j in steps]),
            np.array([c.yaw[j] for c, j in steps]),
            found.predicted,
            found.score,
            time.perf_counter() - start,
            len(steps),
            tuple(len(c) for c in found.candidates),
        )


plan_tool_push = ToolPushPlanner(
    "two_step",
    lambda problem, poses, n: sample_two_steps(problem, poses, n.first, n.keep, n.second),
)
"""The thesis's two-step planner (see the module docstring): two pushes, or one if no kept
state can be pushed again. Call it as ``plan_tool_push(transition, state, rng, config=None, *,
sizes=None)`` (see `ToolPushPlanner.__call__`).
"""

plan_single_push = ToolPushPlanner(
    "single_step", lambda problem, poses, n: sample_best(problem, poses, n.first)
)
"""The best single push: of ``sizes.first`` candidates, the one predicted to put the target
deepest; the arguments are those of `plan_tool_push`.
"""


def plan_random_push(
    state: ToolPushState, rng: np.random.Generator, config: ToolPushConfig | None = None
) -> ToolPushPlan:
    """One random reachable push of the tool (no prediction: `predicted` is NaN).

    Args:
        state: The current state.
        rng: Source of randomness.
        config: Task settings.

    Returns:
        One push.

    Raises:
        InputError: For a `state`, `rng` or `config` of the wrong kind.
        UnreachablePoseError: If the arm can push the tool in no sampled direction.
    """
    config = check_config(config)
    if not isinstance(state, ToolPushState):
        raise InputError(
            f"state must be a ToolPushState (objects and poses), got {type(state).__name__}."
        )
    check_rng(rng)
    start = time.perf_counter()
    cand = sample_tool_pushes(state.objects, state.poses, 1, rng, config)
    return ToolPushPlan(
        cand.origin,
        cand.yaw,
        np.full((1, N_OBJECTS, 3), np.nan),
        math.nan,
        time.perf_counter() - start,
        0,
        (1,),
    )
