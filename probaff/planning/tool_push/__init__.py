"""Chapter 5's two-step tool push: push one box into another to bring it within reach.

The scene (``worlds/scenes/tool_push.yaml``) holds two boxes: the *tool* (o1), which the arm
pushes, and the *target* (o2), which lies outside the reachable region of a receiving arm.
Pushes are executed by the world's arm (``worlds/tabletop.yaml``); that arm could reach the
target too, but the task is tool use, so only the tool is ever pushed. d_p is the scene's
``push.distance`` (0.25 m).

Frames: poses are world ``(x, y, theta)`` (table centre at the origin, z up); pushes are a hand
start ``(x, y)`` and the world yaw of z_p.

Modules:
    config: the task's settings (`ToolPushConfig`).
    region: the receiving arm's reachable region and its signed distance field.
    state: what a planner knows of a scene (`ToolPushState`) and what it loads once.
    candidates: reachable pushes of the tool, sampled as the scene's push skill draws them.
    planners: the thesis's two-step planner, the best single push, a random push.
    trials: seeded trials of every planner, executed open loop in the simulator, and scores.
"""

from probaff.planning.tool_push.candidates import ToolPushCandidates, sample_tool_pushes
from probaff.planning.tool_push.config import SampleSizes, ToolPushConfig
from probaff.planning.tool_push.planners import (
    ToolPushPlan,
    ToolPushPlanner,
    plan_random_push,
    plan_single_push,
    plan_tool_push,
)
from probaff.planning.tool_push.region import ReachableRegion, reachable_region
from probaff.planning.tool_push.state import ToolPushState
from probaff.planning.tool_push.trials import (
    TOOL_PUSH_PLANNERS,
    ToolPushTrial,
    draw_tool_push_episode,
    run_tool_push_trial,
    tool_push_scores,
)

__all__ = [
    "TOOL_PUSH_PLANNERS",
    "ReachableRegion",
    "SampleSizes",
    "ToolPushCandidates",
    "ToolPushConfig",
    "ToolPushPlan",
    "ToolPushPlanner",
    "ToolPushState",
    "ToolPushTrial",
    "draw_tool_push_episode",
    "plan_random_push",
    "plan_single_push",
    "plan_tool_push",
    "reachable_region",
    "run_tool_push_trial",
    "sample_tool_pushes",
    "tool_push_scores",
]
