"""Candidate pushes of the tool, sampled as the scene's push skill draws them.

Candidate pushes follow the scene's push skill, like `probaff.sim.sampling.sample_scene`: a
direction from ``push.direction``, a lateral offset of the push line from the tool's centre
from ``push.lateral_offset`` and a gap between the fingers and the tool from
``push.start_gap``; d_p is ``push.distance``. A candidate is kept if the hand's start pose
clears every object and the world's arm can follow its whole straight path
(`Arm.solve_pushes`, batched over all candidates of a round).

Covered by tests/planning/tool_push/test_tool_push.py.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pymunk
import torch

from probaff._checks import check_count, check_finite, check_shape
from probaff.errors import InputError, UnreachablePoseError
from probaff.planning._checks import check_rng
from probaff.planning.tool_push.config import ToolPushConfig, check_config
from probaff.planning.tool_push.state import tool_push_context
from probaff.sim.geometry import footprint_support
from probaff.sim.sampling import object_shape
from probaff.sim.specs import ObjectSpec
from probaff.sim.tabletop_config import TabletopSpec

__all__ = ["ToolPushCandidates", "sample_tool_pushes"]

_CLEARANCE = 0.003  # gap (m) the hand's start pose keeps from every object, as in sample_scene
_MAX_ROUNDS = 6  # draws of candidate pushes before a state is declared unpushable


@dataclass(frozen=True)
class ToolPushCandidates:
    """Candidate pushes of the tool, from one or more states.

    Attributes:
        origin: (C, 2) world hand starts (m).
        yaw: (C,) world yaws of z_p (rad).
        state: (C,) index of the state each candidate pushes from.
    """

    origin: np.ndarray
    yaw: np.ndarray
    state: np.ndarray

    def __len__(self) -> int:
        return len(self.yaw)


def _hand_free(
    objects: tuple[ObjectSpec, ...],
    poses: np.ndarray,
    start: np.ndarray,
    yaw: np.ndarray,
    world: TabletopSpec,
) -> np.ndarray:
    """(M,) whether each hand start pose keeps clear of every object of one state."""
    space = pymunk.Space()
    for obj, pose in zip(objects, poses, strict=True):
        object_shape(space, obj, pose, _CLEARANCE)
    g = world.gripper
    size = (2 * g.finger_radius, g.push_opening + 2 * g.finger_radius)
    free = np.empty(len(yaw), dtype=bool)
    for i in range(len(yaw)):
        body = pymunk.Body(body_type=pymunk.Body.KINEMATIC)
        body.position, body.angle = (float(start[i, 0]), float(start[i, 1])), float(yaw[i])
        hand = pymunk.Poly.create_box(body, size, radius=_CLEARANCE)
        space.add(body, hand)
        free[i] = not space.shape_query(hand)
        space.remove(body, hand)
    return free


def sample_tool_pushes(
    objects: Sequence[ObjectSpec],
    poses: np.ndarray,
    n: int,
    rng: np.random.Generator,
    config: ToolPushConfig | None = None,
    *,
    allow_empty: bool = False,
) -> ToolPushCandidates:
    """Sample reachable pushes of the tool (object 0), aimed near its centre.

    As `sample_scene` draws a push: a direction from the scene's ``push.direction``, a lateral
    offset of the push line from ``push.lateral_offset`` and a finger gap from
    ``push.start_gap``; the hand starts that gap behind the tool's footprint. A candidate is
    kept if the hand's start pose clears every object and the world's arm can follow the
    whole push of ``push.distance`` (`Arm.solve_pushes`, one batch per round for all states).

    Args:
        objects: The (tool, target) catalogue specs.
        poses: (K, 3) one state, or (S, K, 3) several, world ``(x, y, theta)``.
        n: Candidates per state (a positive integer).
        rng: Source of randomness.
        config: Task settings (the scene).
        allow_empty: Return no candidates for a state the arm cannot push from, instead of
            raising.

    Returns:
        Up to `n` candidates per state (fewer only where valid pushes are rare), grouped by
        state in order.

    Raises:
        InputError: For a bad `n` or pose array.
        UnreachablePoseError: If a state has no reachable push and not `allow_empty`.
    """
    n = check_count("n", n)
    ctx = tool_push_context(check_config(config))
    check_rng(rng)
    given = objects
    objects = tuple(objects) if isinstance(objects, (tuple, list)) else ()
    if not objects or not all(isinstance(o, ObjectSpec) for o in objects):
        raise InputError(
            "objects must be the (tool, target) ObjectSpec of load_catalogue(), the tool "
            f"first, got {given!r}."
        )
    P = np.asarray(poses, dtype=float)
    P = P[None] if P.ndim == 2 else P
    check_shape("poses", P, (None, len(objects), 3))
    check_finite("poses", P)
    S, push = P.shape[0], ctx.scene.push
    tool, fr = objects[0], ctx.world.gripper.finger_radius
    kept: list[list[tuple[np.ndarray, float]]] = [[] for _ in range(S)]
    for _ in range(_MAX_ROUNDS):
        need = [n - len(k) for k in kept]
        rows = [s for s in range(S) if need[s] > 0]
        if not rows:
            break
        starts, yaws, owner = [], [], []
        for s in rows:
            m = math.ceil(1.5 * need[s]) + 4
            phi = rng.uniform(*push.direction, size=m)
            offset = rng.uniform(*push.lateral_offset, size=m)
            gap = rng.uniform(*push.start_gap, size=m)
            d = np.stack([np.cos(phi), np.sin(phi)], -1)
            yp = np.stack([-d[:, 1], d[:, 0]], -1)
            back = np.array([footprint_support(tool, P[s, 0, 2], -di) for di in d]) + fr + gap
            start = P[s, 0, :2] + offset[:, None] * yp - back[:, None] * d
            free = _hand_free(objects, P[s], start, phi, ctx.world)
            starts.append(start[free])
            yaws.append(phi[free])
            owner.append(np.full(int(free.sum()), s))
        start_all, yaw_all = np.concatenate(starts), np.concatenate(yaws)
        owner_all = np.concatenate(owner)
        if len(yaw_all) == 0:
            continue
        ok = ctx.arm.solve_pushes(
            torch.as_tensor(start_all), torch.as_tensor(yaw_all), push.distance
        ).ok.numpy()
        for i in np.flatnonzero(ok):
            s = int(owner_all[i])
            if len(kept[s]) < n:
                kept[s].append((start_all[i], float(yaw_all[i])))
    empty = [s for s in range(S) if not kept[s]]
    if empty and not allow_empty:
        x, y = P[empty[0], 0, :2]
        raise UnreachablePoseError(
            f"no push of the tool at ({x:.3f}, {y:.3f}) is reachable by the arm (base at "
            f"{ctx.world.arm.base_xyz[:2]}) within the scene's push directions "
            f"{push.direction}; place the tool closer to the arm."
        )
    origin = np.array([o for k in kept for o, _ in k], dtype=float).reshape(-1, 2)
    yaw = np.array([a for k in kept for _, a in k], dtype=float)
    state = np.repeat(np.arange(S), [len(k) for k in kept])
    return ToolPushCandidates(origin, yaw, state)
