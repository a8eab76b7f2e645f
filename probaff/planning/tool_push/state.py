"""What the tool-push planners know of a scene (`ToolPushState`) and read once per configuration.

Covered by tests/planning/tool_push/test_tool_push.py.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import numpy as np
import pymunk

from probaff._checks import check_finite, check_shape
from probaff.errors import ConfigError, InputError
from probaff.planning.tool_push.config import N_OBJECTS, ToolPushConfig
from probaff.planning.tool_push.region import ReachableRegion, reachable_region
from probaff.sim.arm import Arm, load_arm
from probaff.sim.sampling import object_shape
from probaff.sim.specs import ObjectSpec
from probaff.sim.tabletop_config import SceneSpec, TabletopSpec, load_scene, load_tabletop

__all__ = ["ToolPushContext", "ToolPushState", "check_state", "tool_push_context"]

_OVERLAP = 0.002  # deeper interpenetration (m) of the two footprints is an overlap


@dataclass(frozen=True, eq=False)
class ToolPushState:
    """What the planner knows of a scene: the two boxes and their poses.

    Attributes:
        objects: ``(tool, target)`` catalogue specs; the tool (o1) is the one pushed.
        poses: (2, 3) world ``(x, y, theta)`` of the tool and the target.

    Raises:
        InputError: For anything but two objects, a pose array that is not a finite (2, 3),
            a centre off the table, or footprints that overlap (by more than 2 mm: objects
            at rest against each other interpenetrate slightly in the physics).
    """

    objects: tuple[ObjectSpec, ...]
    poses: np.ndarray

    def __post_init__(self) -> None:
        objects = tuple(self.objects) if isinstance(self.objects, (tuple, list)) else ()
        if len(objects) != N_OBJECTS or not all(isinstance(o, ObjectSpec) for o in objects):
            raise InputError(
                "ToolPushState.objects must be the (tool, target) pair of ObjectSpec from "
                f"load_catalogue(), got {self.objects!r}."
            )
        poses = np.array(self.poses, dtype=float)
        check_shape("ToolPushState.poses", poses, (N_OBJECTS, 3))
        check_finite("ToolPushState.poses", poses)
        poses.setflags(write=False)
        object.__setattr__(self, "objects", objects)
        object.__setattr__(self, "poses", poses)
        hx, hy = (0.5 * s for s in load_tabletop().table_size)
        for k, name in enumerate(("tool", "target")):
            if abs(poses[k, 0]) > hx or abs(poses[k, 1]) > hy:
                raise InputError(
                    f"ToolPushState: the {name}'s centre ({poses[k, 0]:.3f}, {poses[k, 1]:.3f}) "
                    f"is off the {2 * hx:.2f} x {2 * hy:.2f} m table; place it on the table."
                )
        space = pymunk.Space()
        tool = object_shape(space, objects[0], poses[0], 0.0)
        object_shape(space, objects[1], poses[1], 0.0)
        depth = [p.distance for h in space.shape_query(tool) for p in h.contact_point_set.points]
        if depth and min(depth) < -_OVERLAP:
            raise InputError(
                f"ToolPushState: the tool ({objects[0].name}) and the target "
                f"({objects[1].name}) overlap at poses {poses.tolist()}; move them apart."
            )


@dataclass(frozen=True)
class ToolPushContext:
    """What every planner reads, built once per configuration.

    Attributes:
        scene: The scene template (objects, push skill).
        world: The tabletop world.
        arm: The world's arm, which pushes.
        region: The receiving arm's reachable region.
    """

    scene: SceneSpec
    world: TabletopSpec
    arm: Arm
    region: ReachableRegion


@lru_cache(maxsize=8)
def tool_push_context(config: ToolPushConfig) -> ToolPushContext:
    """The scene, world, arm and region of `config`, loaded once per process.

    Raises:
        ConfigError: If the scene does not hold exactly a tool and a target.
    """
    scene = load_scene(config.scene)
    world = load_tabletop()
    if len(scene.objects) != N_OBJECTS:
        raise ConfigError(
            f"scene {config.scene!r} has {len(scene.objects)} objects; the tool push needs a "
            "tool and a target (see worlds/scenes/tool_push.yaml)."
        )
    return ToolPushContext(scene, world, load_arm(world.arm), reachable_region(config))


def check_state(state: Any, ctx: ToolPushContext) -> ToolPushState:
    """`state`, or `InputError` unless it is a `ToolPushState` that two pushes can solve."""
    if not isinstance(state, ToolPushState):
        raise InputError(
            f"state must be a ToolPushState (objects and poses), got {type(state).__name__}."
        )
    depth = float(ctx.region.depth(state.poses[1, :2]))
    bound = 2 * ctx.scene.push.distance
    if depth < -bound:
        raise InputError(
            f"the target at ({state.poses[1, 0]:.3f}, {state.poses[1, 1]:.3f}) lies "
            f"{-depth:.3f} m outside the reachable region; two pushes of d_p = "
            f"{ctx.scene.push.distance} m move it at most {bound:.2f} m, so it cannot be brought "
            "within reach: place it closer to the receiving arm (ToolPushConfig.goal_base_xy)."
        )
    return state
