"""The tool push's settings: sample sizes of the planners, the receiving arm, start states.

Covered by tests/planning/tool_push/test_tool_push.py.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from probaff._checks import check_count, check_finite, check_positive
from probaff.errors import InputError
from probaff.planning._checks import check_instance

__all__ = ["N_OBJECTS", "SampleSizes", "ToolPushConfig", "check_config"]

N_OBJECTS = 2
"""Objects of the task: the tool (o1, pushed) and the target (o2)."""


@dataclass(frozen=True)
class SampleSizes:
    """How many pushes the two-step planner samples and keeps.

    Attributes:
        first: Pushes of the tool sampled at the start state (thesis: 100).
        keep: Of those, the ones kept because they leave the boxes closest (thesis: 10).
        second: Pushes sampled from each kept predicted state (thesis: 100).

    Raises:
        InputError: For a size that is not a positive integer, or `keep` above `first`.
    """

    first: int = 100
    keep: int = 10
    second: int = 100

    def __post_init__(self) -> None:
        for name in ("first", "keep", "second"):
            value = check_count(f"SampleSizes.{name}", getattr(self, name))
            object.__setattr__(self, name, value)
        if self.keep > self.first:
            raise InputError(
                f"SampleSizes: keep={self.keep} exceeds first={self.first}; keep at most as "
                "many first pushes as are sampled."
            )


@dataclass(frozen=True)
class ToolPushConfig:
    """Settings of the tool-push task and its planners (each default written once, here).

    Attributes:
        scene: Scene template of the start states and the pushes.
        sizes: Pushes the two-step planner samples and keeps (the thesis's 100, 10, 100); the
            single-push planner samples ``sizes.first``.
        sim_sizes: `sizes` of ``"two_step_sim"``, whose transitions are physics rollouts.
        region_resolution: Grid spacing of the region's IK mask (m).
        region_yaws: Tool yaws tried per grid point; a point is reachable with any of them.
        goal_base_xy: World ``(x, y)`` of the receiving arm's base (m); its reach is the
            reachable region.
        min_outside: A start state's target lies at least this far outside the region (m).
        max_outside: ... and at most this far (m); two pushes of d_p cannot move it further
            than 2 d_p.
        max_draws: Scene draws tried for one episode before giving up.

    Raises:
        InputError: For a field out of range.
    """

    scene: str = "tool_push"
    sizes: SampleSizes = SampleSizes()
    sim_sizes: SampleSizes = SampleSizes(24, 4, 12)
    region_resolution: float = 0.02
    region_yaws: int = 2
    goal_base_xy: tuple[float, float] = (-1.0, 0.0)
    min_outside: float = 0.03
    max_outside: float = 0.25
    max_draws: int = 500

    def __post_init__(self) -> None:
        if not isinstance(self.scene, str) or not self.scene:
            raise InputError(f"ToolPushConfig.scene must be a scene name, got {self.scene!r}.")
        for name in ("sizes", "sim_sizes"):
            check_instance(
                getattr(self, name), SampleSizes, f"ToolPushConfig.{name} must be a SampleSizes"
            )
        for name in ("region_yaws", "max_draws"):
            value = check_count(f"ToolPushConfig.{name}", getattr(self, name))
            object.__setattr__(self, name, value)
        base = tuple(self.goal_base_xy) if isinstance(self.goal_base_xy, (tuple, list)) else ()
        if len(base) != 2:
            raise InputError(
                f"ToolPushConfig.goal_base_xy must be a world (x, y) pair, got "
                f"{self.goal_base_xy!r}."
            )
        check_finite("ToolPushConfig.goal_base_xy", np.asarray(base, dtype=float))
        object.__setattr__(self, "goal_base_xy", (float(base[0]), float(base[1])))
        check_positive("ToolPushConfig.region_resolution", self.region_resolution)
        check_positive("ToolPushConfig.min_outside", self.min_outside, allow_zero=True)
        check_positive("ToolPushConfig.max_outside", self.max_outside)
        if self.min_outside > self.max_outside:
            raise InputError(
                f"ToolPushConfig.min_outside={self.min_outside} exceeds max_outside="
                f"{self.max_outside}; swap them."
            )


def check_config(config: Any) -> ToolPushConfig:
    """`config`, the defaults for ``None``, or `InputError` for anything else."""
    if config is None:
        return ToolPushConfig()
    return check_instance(
        config, ToolPushConfig, "config must be a ToolPushConfig (or None for the defaults)"
    )
