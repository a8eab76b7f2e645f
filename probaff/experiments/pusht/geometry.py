"""Push-T's geometry, as gym-pusht 0.1.8 builds it: the T, its pose frames, distances, costs.

gym-pusht's block is a T of two boxes on one body: a bar ``[-60, 60] x [0, 30]`` and a stem
``[-15, 15] x [30, 120]`` (pixels, body frame), its centre of gravity at ``(0, 45)``; the agent
is a disc of radius 15; the walls leave the agent's centre inside ``[22, 489]`` on both axes;
the goal is the T at ``(256, 256, pi / 4)``. The environment observes the body's origin and
angle; probaff works with the pose of the centre of gravity (`cog_pose`), about which the block
turns, so that a push's effect does not depend on where the body's origin happens to lie.

Units. probaff's datasets hold metres; Push-T's world is 512 pixels wide, and `PX` metres per
pixel (a millimetre) makes it a half-metre table. Everything here is in pixels; the data layer
converts (`PX`).

Frames. A pose is ``(x, y, theta)``: the centre of gravity in the world and the block's angle.
The block frame has its origin at the centre of gravity, so the T's outline is
`RECTS` shifted by ``-COG``.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = [
    "AGENT_RADIUS",
    "ARENA",
    "COG",
    "GOAL_ORIGIN_POSE",
    "INERTIA",
    "KEYPOINTS",
    "OUTLINE",
    "PERIMETER",
    "PX",
    "RECTS",
    "cog_pose",
    "contact_points",
    "distance_to_tee",
    "keypoint_cost",
    "origin_pose",
    "to_block",
    "to_world",
]

PX = 0.001
"""Metres per Push-T pixel, for probaff's datasets (a 512 mm arena)."""
AGENT_RADIUS = 15.0
"""Radius of the agent's disc (px)."""
ARENA = (22.0, 489.0)
"""Range of the agent's centre, on both axes, that keeps it off the walls (px)."""
COG = np.array([0.0, 45.0])
"""The block's centre of gravity in its body frame (px): the mean of its two boxes' centres."""
INERTIA = 3000.0
"""The block's moment of inertia about its centre of gravity (px^2, mass 1): gym-pusht adds
the bar's moment about the body origin twice, ``2 * ((120^2 + 30^2) / 12 + 15^2)``."""
GOAL_ORIGIN_POSE = np.array([256.0, 256.0, math.pi / 4])
"""The goal's body-origin pose (px, px, rad)."""
RECTS = np.array([[-60.0, 0.0, 60.0, 30.0], [-15.0, 30.0, 15.0, 120.0]]) - np.r_[COG, COG]
"""The two boxes ``(x0, y0, x1, y1)`` in the block frame (centre of gravity at 0)."""
OUTLINE = (
    np.array(
        [[-60, 0], [60, 0], [60, 30], [15, 30], [15, 120], [-15, 120], [-15, 30], [-60, 30]],
        dtype=float,
    )
    - COG
)
"""The T's outline in the block frame, counter-clockwise (px)."""
KEYPOINTS = OUTLINE
"""The points whose distance to the goal's scores a pose (`keypoint_cost`)."""
_EDGES = np.roll(OUTLINE, -1, axis=0) - OUTLINE
_LENGTHS = np.linalg.norm(_EDGES, axis=1)
_STARTS = np.r_[0.0, np.cumsum(_LENGTHS)[:-1]]
PERIMETER = float(_LENGTHS.sum())
"""Length of the T's outline (480 px)."""


def _rot(theta: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
    return np.cos(theta), np.sin(theta)


def cog_pose(origin: np.ndarray) -> np.ndarray:
    """Centre-of-gravity poses from gym-pusht's body-origin poses.

    Args:
        origin: (..., 3) body-origin ``(x, y, angle)`` (px, px, rad).

    Returns:
        (..., 3) ``(x, y, angle)`` of the centre of gravity (the angle unchanged).
    """
    origin = np.asarray(origin, dtype=float)
    c, s = _rot(origin[..., 2])
    x = origin[..., 0] + c * COG[0] - s * COG[1]
    y = origin[..., 1] + s * COG[0] + c * COG[1]
    return np.stack([x, y, origin[..., 2]], axis=-1)


def origin_pose(pose: np.ndarray) -> np.ndarray:
    """Body-origin poses from centre-of-gravity poses (the inverse of `cog_pose`).

    Args:
        pose: (..., 3) centre-of-gravity ``(x, y, angle)``.

    Returns:
        (..., 3) body-origin ``(x, y, angle)``.
    """
    pose = np.asarray(pose, dtype=float)
    c, s = _rot(pose[..., 2])
    x = pose[..., 0] - (c * COG[0] - s * COG[1])
    y = pose[..., 1] - (s * COG[0] + c * COG[1])
    return np.stack([x, y, pose[..., 2]], axis=-1)


def to_world(pose: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Block-frame points in the world.

    Args:
        pose: (..., 3) centre-of-gravity poses.
        points: (..., P, 2) block-frame points (broadcast against `pose`'s batch).

    Returns:
        (..., P, 2) world points.
    """
    pose = np.asarray(pose, dtype=float)
    c, s = _rot(pose[..., 2:3])
    px, py = points[..., 0], points[..., 1]
    return np.stack([pose[..., 0:1] + c * px - s * py, pose[..., 1:2] + s * px + c * py], axis=-1)


def to_block(pose: np.ndarray, points: np.ndarray) -> np.ndarray:
    """World points in the block frame of `pose` (the inverse of `to_world`).

    Args:
        pose: (3,) a centre-of-gravity pose.
        points: (P, 2) world points.

    Returns:
        (P, 2) block-frame points.
    """
    c, s = math.cos(pose[2]), math.sin(pose[2])
    d = np.asarray(points, dtype=float) - pose[:2]
    return np.stack([c * d[..., 0] + s * d[..., 1], -s * d[..., 0] + c * d[..., 1]], axis=-1)


def contact_points(s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Points and outward normals on the T's outline at arc lengths `s`.

    Args:
        s: (K,) arc lengths along `OUTLINE` from its first vertex (px, taken modulo
            `PERIMETER`).

    Returns:
        ``(points, normals)``: (K, 2) block-frame points and (K, 2) unit outward normals.
    """
    s = np.mod(np.asarray(s, dtype=float), PERIMETER)
    edge = np.clip(np.searchsorted(_STARTS, s, side="right") - 1, 0, len(_STARTS) - 1)
    t = (s - _STARTS[edge]) / _LENGTHS[edge]
    points = OUTLINE[edge] + t[:, None] * _EDGES[edge]
    d = _EDGES[edge] / _LENGTHS[edge][:, None]
    normals = np.stack([d[:, 1], -d[:, 0]], axis=-1)  # counter-clockwise outline: right side
    return points, normals


def distance_to_tee(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Distance from block-frame points to the T, and the T's nearest points.

    Args:
        points: (..., 2) block-frame points.

    Returns:
        ``(distance, nearest)``: (...) distances (0 inside the T) and (..., 2) nearest points
        of the T.
    """
    p = np.asarray(points, dtype=float)
    best_d = np.full(p.shape[:-1], np.inf)
    best_q = np.zeros_like(p)
    for x0, y0, x1, y1 in RECTS:
        q = np.stack([np.clip(p[..., 0], x0, x1), np.clip(p[..., 1], y0, y1)], axis=-1)
        d = np.linalg.norm(p - q, axis=-1)
        closer = d < best_d
        best_d = np.where(closer, d, best_d)
        best_q = np.where(closer[..., None], q, best_q)
    return best_d, best_q


def keypoint_cost(pose: np.ndarray, goal: np.ndarray) -> np.ndarray:
    """Mean distance (px) of the T's outline vertices at `pose` from theirs at `goal`.

    Args:
        pose: (..., 3) centre-of-gravity poses.
        goal: (3,) the goal's centre-of-gravity pose.

    Returns:
        (...) mean vertex distances; 0 at the goal.
    """
    pose = np.asarray(pose, dtype=float)
    at = to_world(pose, np.broadcast_to(KEYPOINTS, (*pose.shape[:-1], *KEYPOINTS.shape)))
    target = to_world(np.asarray(goal, dtype=float), KEYPOINTS)
    return np.linalg.norm(at - target, axis=-1).mean(axis=-1)
