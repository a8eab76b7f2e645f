"""Push-T scored as LeRobot scores it: success with its interval and the environment's reward.

gym-pusht 0.1.8 (``gym_pusht/envs/pusht.py``, ``PushTEnv.step``) rewards a step with
``clip(coverage / success_threshold, 0, 1)`` where ``success_threshold = 0.95`` and the coverage
is the fraction of the goal's area the block covers; it terminates (success) when the coverage
exceeds 0.95. LeRobot's evaluation reports ``pc_success`` (episodes that succeeded) and
``avg_max_reward`` (the mean over episodes of the largest reward of each). The reward is a
non-decreasing function of the coverage, so an episode's maximum reward is the reward of its
maximum coverage: `env_reward` of the record's ``max_coverage``.

`DIFFUSION_POLICY` is LeRobot's published diffusion policy on gym-pusht (500 episodes,
``obs_type: pixels_agent_pos``), in those units; `score` gives a set of episodes the same
numbers, with the raw coverage beside them.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from probaff._checks import real_float64
from probaff.errors import InputError
from probaff.eval.metrics import wilson_interval

__all__ = [
    "DIFFUSION_POLICY",
    "OBSERVATION_NAMES",
    "SUCCESS_THRESHOLD",
    "PublishedResult",
    "env_reward",
    "reference_row",
    "score",
]

SUCCESS_THRESHOLD = 0.95
"""gym-pusht's ``success_threshold``: success when the coverage exceeds it; reward = cov / it."""

OBSERVATION_NAMES = {"state": "state", "pixels": "pixels_agent_pos"}
"""What each of the study's observation modes is in gym-pusht's ``obs_type`` names."""


@dataclass(frozen=True)
class PublishedResult:
    """A published Push-T result in LeRobot's units.

    Attributes:
        name: The policy.
        episodes: Evaluation episodes.
        success_rate: ``pc_success / 100``.
        avg_max_reward: Mean over episodes of the maximum environment reward.
        observation: gym-pusht's ``obs_type`` the policy observed.
    """

    name: str
    episodes: int
    success_rate: float
    avg_max_reward: float
    observation: str


DIFFUSION_POLICY = PublishedResult(
    name="diffusion policy (LeRobot)",
    episodes=500,
    success_rate=0.638,
    avg_max_reward=0.959,
    observation="pixels_agent_pos",
)
"""LeRobot's diffusion policy on gym-pusht (its model card's evaluation): the goal."""


def env_reward(coverage: Any) -> np.ndarray:
    """gym-pusht's reward of a coverage: ``clip(coverage / 0.95, 0, 1)``.

    Args:
        coverage: Coverages in [0, 1], any shape.

    Returns:
        The rewards, the same shape.

    Raises:
        InputError: For coverages that are not finite numbers in [0, 1].
    """
    cov = real_float64(coverage)
    if cov is None:
        raise InputError(f"coverage must be numbers in [0, 1], got {coverage!r}.")
    if not np.isfinite(cov).all() or (cov < 0).any() or (cov > 1).any():
        raise InputError(
            f"coverage must be finite numbers in [0, 1] (the goal's covered fraction), got "
            f"{cov.ravel()[:5].tolist()}."
        )
    return np.clip(cov / SUCCESS_THRESHOLD, 0.0, 1.0)


def score(records: Sequence[dict[str, Any]]) -> dict[str, Any]:
    """Success with its Wilson 95 % interval, mean maximum reward and coverage of episodes.

    Args:
        records: Episode records with ``success``, ``max_coverage`` and, for episodes
            observed from pixels, ``observation`` (``"state"`` when absent).

    Returns:
        ``observation`` (gym-pusht's ``obs_type`` name; several joined by ``+``),
        ``episodes``, ``successes``, ``success_rate``, ``success_low``, ``success_high``,
        ``max_reward`` (LeRobot's ``avg_max_reward``) and ``max_coverage`` (the raw mean
        maximum coverage).

    Raises:
        InputError: For no records.
    """
    if not records:
        raise InputError("score needs at least one episode record.")
    k = sum(bool(r["success"]) for r in records)
    lo, hi = wilson_interval(k, len(records))
    cov = np.array([float(r["max_coverage"]) for r in records])
    seen = dict.fromkeys(
        OBSERVATION_NAMES.get(str(r.get("observation", "state")), str(r.get("observation")))
        for r in records
    )
    return {
        "observation": "+".join(seen),
        "episodes": len(records),
        "successes": k,
        "success_rate": k / len(records),
        "success_low": lo,
        "success_high": hi,
        "max_reward": float(env_reward(cov).mean()),
        "max_coverage": float(cov.mean()),
    }


def reference_row(result: PublishedResult = DIFFUSION_POLICY) -> dict[str, Any]:
    """A published result as a row of the planners' table.

    Its interval is Wilson's for the published rate's successes (rate x episodes, rounded);
    its coverage is not published (NaN).
    """
    k = round(result.success_rate * result.episodes)
    lo, hi = wilson_interval(k, result.episodes)
    return {
        "planner": result.name,
        "observation": result.observation,
        "episodes": result.episodes,
        "successes": k,
        "success_rate": result.success_rate,
        "success_low": lo,
        "success_high": hi,
        "max_reward": result.avg_max_reward,
        "max_coverage": float("nan"),
    }
