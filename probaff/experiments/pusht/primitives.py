"""Push primitives on the T: a contact, a direction and a length, turned into agent targets.

A primitive is ``(s, phi, length)``: the contact at arc length `s` along the T's outline
(`probaff.experiments.pusht.geometry.contact_points`), the push's angle `phi` from the inward
normal there (rad, positive counter-clockwise in the block frame) and the distance the agent's
target travels past first contact (px). `primitive_actions` turns it into the agent targets that
gym-pusht takes at 10 Hz: the agent leaves the block along the outward normal of its nearest
point, goes around the T on the shortest path that keeps `PrimitiveSettings.clearance` from it
(a visibility graph over the corners of the T grown by the agent's radius and the clearance),
comes in along the contact's normal to `PrimitiveSettings.gap` from the outline, waits, pushes
at `PrimitiveSettings.push_speed`, and holds the last target while the agent settles.
"""

from __future__ import annotations

import heapq
import itertools
import math
from dataclasses import dataclass

import numpy as np

from probaff._checks import check_count, check_positive
from probaff.errors import InputError
from probaff.experiments.pusht.geometry import (
    AGENT_RADIUS,
    ARENA,
    GYM_TEE,
    TeeGeometry,
    contact_points,
    distance_to_tee,
    to_block,
    to_world,
)

__all__ = [
    "PrimitiveSettings",
    "PushPlan",
    "feasible_starts",
    "primitive_actions",
    "push_frames",
    "sample_primitives",
]


@dataclass(frozen=True)
class PrimitiveSettings:
    """How a push primitive becomes agent targets, and the range primitives are drawn from.

    Attributes:
        clearance: Gap (px) kept between the agent's disc and the T on the way around it.
        gap: Gap (px) between the agent's disc and the outline where the push starts.
        approach_speed: Target travel per control step on the way around the T (px).
        push_speed: Target travel per control step while pushing (px).
        wait: Control steps the target holds at the push's start.
        settle: Control steps the target holds at the push's end.
        max_angle: Largest angle of a push from the inward normal (rad).
        min_length: Shortest push (px).
        max_length: Longest push (px).
    """

    clearance: float = 10.0
    gap: float = 3.0
    approach_speed: float = 20.0
    push_speed: float = 8.0
    wait: int = 2
    settle: int = 3
    max_angle: float = 0.5
    min_length: float = 3.0
    max_length: float = 60.0

    def __post_init__(self) -> None:
        for name in ("clearance", "gap", "approach_speed", "push_speed", "max_angle"):
            check_positive(f"PrimitiveSettings.{name}", getattr(self, name))
        check_count("PrimitiveSettings.wait", self.wait, minimum=0)
        check_count("PrimitiveSettings.settle", self.settle, minimum=0)
        check_positive("PrimitiveSettings.min_length", self.min_length)
        if self.max_length < self.min_length:
            raise InputError(
                f"PrimitiveSettings.max_length ({self.max_length}) must be at least min_length "
                f"({self.min_length})."
            )
        if self.gap >= self.clearance:
            raise InputError("PrimitiveSettings.gap must be smaller than its clearance.")


@dataclass(frozen=True)
class PushPlan:
    """The agent targets of one primitive.

    Attributes:
        actions: (T, 2) world agent targets, one per control step.
        push_start: Index of the first pushing target (the targets before it go around the T
            and wait).
        feasible: Whether the push can start inside the arena without the agent overlapping
            the T.
    """

    actions: np.ndarray
    push_start: int
    feasible: bool


def sample_primitives(
    rng: np.random.Generator, n: int, settings: PrimitiveSettings, tee: TeeGeometry = GYM_TEE
) -> np.ndarray:
    """`n` primitives drawn uniformly: contact along the outline, angle, log-uniform length.

    Args:
        rng: The random generator.
        n: Number of primitives.
        settings: Their ranges.
        tee: The T (the contact is drawn along its perimeter).

    Returns:
        (n, 3) ``(s, phi, length)``.
    """
    s = rng.uniform(0.0, tee.perimeter, n)
    phi = rng.uniform(-settings.max_angle, settings.max_angle, n)
    lo, hi = math.log(settings.min_length), math.log(settings.max_length)
    return np.stack([s, phi, np.exp(rng.uniform(lo, hi, n))], axis=-1)


def push_frames(
    prims: np.ndarray, settings: PrimitiveSettings, tee: TeeGeometry = GYM_TEE
) -> dict[str, np.ndarray]:
    """The block-frame geometry of primitives.

    Args:
        prims: (K, 3) ``(s, phi, length)``.
        settings: Where a push starts (`PrimitiveSettings.gap`).
        tee: The T.

    Returns:
        ``contact`` (K, 2) and ``normal`` (K, 2) on the outline, ``direction`` (K, 2) unit
        push directions, ``start`` (K, 2) the agent's centre where the push starts, all in the
        block frame, and ``yaw`` (K,) the push direction's block-frame angle.
    """
    prims = np.asarray(prims, dtype=float)
    contact, normal = contact_points(prims[:, 0], tee)
    yaw = np.arctan2(-normal[:, 1], -normal[:, 0]) + prims[:, 1]
    direction = np.stack([np.cos(yaw), np.sin(yaw)], axis=-1)
    start = contact + normal * (AGENT_RADIUS + settings.gap)
    return {
        "contact": contact,
        "normal": normal,
        "direction": direction,
        "start": start,
        "yaw": yaw,
    }


def feasible_starts(
    pose: np.ndarray, prims: np.ndarray, settings: PrimitiveSettings, tee: TeeGeometry = GYM_TEE
) -> np.ndarray:
    """(K,) whether each of (K, 3) primitives starts clear of the T and inside the arena.

    Args:
        pose: (3,) the T's centre-of-gravity pose (px, px, rad).
        prims: (K, 3) ``(s, phi, length)``.
        settings: Where a push starts (`PrimitiveSettings.gap`).
        tee: The T.
    """
    start = push_frames(prims, settings, tee)["start"]
    d, _ = distance_to_tee(start, tee)
    world = to_world(pose, start)
    inside = np.all((world >= ARENA[0]) & (world <= ARENA[1]), axis=-1)
    return (d >= AGENT_RADIUS + settings.gap - 1e-6) & inside


def _segment_hits(a: np.ndarray, b: np.ndarray, grow: float, rects: np.ndarray) -> bool:
    """Whether segment a-b (block frame) passes through a box `rects` (2, 4) grown by `grow`."""
    d = b - a
    for x0, y0, x1, y1 in rects:
        lo, hi = 0.0, 1.0
        ok = True
        for k, (mn, mx) in enumerate(((x0 - grow, x1 + grow), (y0 - grow, y1 + grow))):
            if abs(d[k]) < 1e-12:
                if a[k] <= mn or a[k] >= mx:
                    ok = False
                    break
                continue
            t0, t1 = sorted(((mn - a[k]) / d[k], (mx - a[k]) / d[k]))
            lo, hi = max(lo, t0), min(hi, t1)
            if hi - lo <= 1e-9:
                ok = False
                break
        if ok and (hi - lo) * float(np.hypot(*d)) > 1e-6:
            return True
    return False


def _corners(grow: float, rects: np.ndarray) -> np.ndarray:
    """The convex corners of the T's boxes `rects` (2, 4) grown by `grow` (block frame)."""
    (bx0, by0, bx1, by1), (sx0, _, sx1, sy1) = rects
    return np.array(
        [
            [bx0 - grow, by0 - grow],
            [bx1 + grow, by0 - grow],
            [bx1 + grow, by1 + grow],
            [sx1 + grow, sy1 + grow],
            [sx0 - grow, sy1 + grow],
            [bx0 - grow, by1 + grow],
        ]
    )


def _shortest_path(
    start: np.ndarray, goal: np.ndarray, grow: float, free: float, rects: np.ndarray
) -> np.ndarray:
    """Shortest block-frame path start -> goal that keeps `free` from the T (visibility graph)."""
    nodes = np.vstack([start, goal, _corners(grow, rects)])
    n = len(nodes)
    dist = np.full(n, np.inf)
    prev = np.full(n, -1)
    dist[0] = 0.0
    heap = [(0.0, 0)]
    done = np.zeros(n, dtype=bool)
    while heap:
        d, i = heapq.heappop(heap)
        if done[i]:
            continue
        done[i] = True
        if i == 1:
            break
        for j in range(n):
            if done[j] or _segment_hits(nodes[i], nodes[j], free, rects):
                continue
            nd = d + float(np.linalg.norm(nodes[j] - nodes[i]))
            if nd < dist[j]:
                dist[j], prev[j] = nd, i
                heapq.heappush(heap, (nd, j))
    if not np.isfinite(dist[1]):
        return np.vstack([start, goal])
    path = [1]
    while path[-1] != 0:
        path.append(int(prev[path[-1]]))
    return nodes[path[::-1]]


def _resample(path: np.ndarray, step: float) -> np.ndarray:
    """Points every `step` along a polyline, its first point left out, its last kept."""
    out: list[np.ndarray] = []
    for a, b in itertools.pairwise(path):
        length = float(np.linalg.norm(b - a))
        k = max(1, math.ceil(length / step))
        out.extend(a + (b - a) * (i / k) for i in range(1, k + 1))
    return np.array(out) if out else np.zeros((0, 2))


def _inside_arena(points: np.ndarray) -> bool:
    return bool(np.all((points >= ARENA[0]) & (points <= ARENA[1])))


def primitive_actions(
    pose: np.ndarray,
    agent: np.ndarray,
    prim: np.ndarray,
    settings: PrimitiveSettings,
    tee: TeeGeometry = GYM_TEE,
) -> PushPlan:
    """The agent targets of one primitive from the block's pose and the agent's position.

    Args:
        pose: (3,) the block's centre-of-gravity pose (px, px, rad).
        agent: (2,) the agent's world position (px).
        prim: (3,) ``(s, phi, length)``.
        settings: Speeds, clearance, gap and waits.
        tee: The T.

    Returns:
        The targets, clamped to the arena, and whether the push is feasible.
    """
    frames = push_frames(np.asarray(prim, dtype=float)[None], settings, tee)
    geo = {k: v[0] for k, v in frames.items()}
    grow = AGENT_RADIUS + settings.clearance
    free = AGENT_RADIUS + 1.0
    start_d, _ = distance_to_tee(geo["start"][None], tee)
    feasible = bool(start_d[0] >= AGENT_RADIUS + settings.gap - 1e-6)
    entry = geo["start"] + geo["normal"] * (settings.clearance - settings.gap + 1.0)
    here = to_block(pose, np.asarray(agent, dtype=float)[None])[0]
    d, near = distance_to_tee(here[None], tee)
    points = [here]
    if d[0] < grow:  # leave along the outward normal of the nearest point first
        away = here - near[0]
        norm = float(np.linalg.norm(away))
        away = away / norm if norm > 1e-9 else -geo["direction"]
        points.append(near[0] + away * (grow + 1.0))
    route = _shortest_path(points[-1], entry, grow + 1.0, free, tee.rects)
    path_block = np.vstack([points[0], *points[1:], route[1:]])
    around = _resample(path_block, settings.approach_speed)
    come_in = _resample(np.vstack([entry, geo["start"]]), settings.push_speed)
    wait = np.repeat(geo["start"][None], settings.wait, axis=0)
    total = settings.gap + float(prim[2])
    push_end = geo["start"] + geo["direction"] * total
    push = _resample(np.vstack([geo["start"], push_end]), settings.push_speed)
    hold = np.repeat(push_end[None], settings.settle, axis=0)
    block = np.vstack([around, come_in, wait, push, hold])
    world = to_world(np.asarray(pose, dtype=float), block)
    feasible = feasible and _inside_arena(to_world(np.asarray(pose), geo["start"][None]))
    return PushPlan(
        actions=np.clip(world, *ARENA),
        push_start=len(around) + len(come_in) + len(wait),
        feasible=feasible,
    )
