"""Planar geometry of footprints and of the pushing frame.

Pushing frame (chapters 4 and 5): origin at the hand's start pose, z_p along the push, y_p to
the left of it (z_p rotated +90 degrees about the world's up axis), x_p pointing down into the
table so the frame is right-handed. Angles (theta, Delta theta_p) are counter-clockwise about the
world's up axis, in radians.
"""

from __future__ import annotations

import math

import numpy as np
import pymunk

from probaff._checks import check_count, check_finite, check_shape
from probaff.sim.specs import ObjectSpec

__all__ = [
    "body_pose",
    "contact_depth",
    "convex_penetration",
    "footprint_penetration",
    "footprint_polygon",
    "footprint_support",
    "friction_points",
    "push_frame_effect",
    "rect_disc_penetration",
    "to_push_frame",
]


def body_pose(body: pymunk.Body) -> tuple[float, float, float]:
    """The world pose ``(x, y, angle)`` of `body` (m, m, rad), as the simulators record it."""
    return (body.position.x, body.position.y, body.angle)


def contact_depth(space: pymunk.Space, shape: pymunk.Shape) -> float:
    """Deepest overlap (m) of `shape` with any other shape of `space` (0 if none overlaps).

    Each contact's depth is taken from its two points and normal, not from pymunk's
    ``ContactPoint.distance``: for a pair that Chipmunk collides in the other order (a polygon
    against a segment or a circle, a segment against a circle) ``Space.shape_query`` reports
    that distance with its sign flipped (pymunk 7.3), so a box 3 mm into a wall read as 3 mm
    apart from it.

    Args:
        space: The space.
        shape: One of its shapes.

    Returns:
        The largest penetration depth, >= 0.
    """
    deepest = 0.0
    for hit in space.shape_query(shape):
        points = hit.contact_point_set
        for p in points.points:
            deepest = max(deepest, -float((p.point_b - p.point_a).dot(points.normal)))
    return deepest


def convex_penetration(a: np.ndarray, b: np.ndarray) -> float:
    """Depth (m) by which two convex polygons overlap (<= 0: apart), by separating axes.

    The depth is the least overlap of the two polygons' projections on the normals of their
    edges: the distance one must move to separate them; a negative value is the gap along the
    best separating normal.

    Args:
        a: (N, 2) vertices of the first polygon, in order round it.
        b: (M, 2) vertices of the second.

    Returns:
        The penetration depth (m).
    """
    depth = math.inf
    for poly in (a, b):
        edges = np.roll(poly, -1, axis=0) - poly
        for ex, ey in edges:
            n = np.array([-ey, ex]) / math.hypot(ex, ey)
            pa, pb = a @ n, b @ n
            depth = min(depth, min(pa.max() - pb.min(), pb.max() - pa.min()))
    return float(depth)


def rect_disc_penetration(
    centre: np.ndarray, size: tuple[float, float], yaw: float, disc: np.ndarray, radius: float
) -> float:
    """Depth (m) by which a rectangle and a disc overlap (<= 0: apart, minus the gap).

    Args:
        centre: (2,) the rectangle's centre.
        size: Its extents along its own x and y (m).
        yaw: Its rotation (rad, counter-clockwise).
        disc: (2,) the disc's centre.
        radius: The disc's radius (m).
    """
    c, s = math.cos(yaw), math.sin(yaw)
    dx, dy = float(disc[0] - centre[0]), float(disc[1] - centre[1])
    u, v = abs(c * dx + s * dy), abs(-s * dx + c * dy)
    hx, hy = 0.5 * size[0], 0.5 * size[1]
    if u <= hx and v <= hy:  # the disc's centre lies inside the rectangle
        return float(radius + min(hx - u, hy - v))
    return float(radius - math.hypot(max(u - hx, 0.0), max(v - hy, 0.0)))


def _rect_corners(centre: np.ndarray, size: tuple[float, float], yaw: float) -> np.ndarray:
    """(4, 2) corners of a rectangle, counter-clockwise."""
    c, s = math.cos(yaw), math.sin(yaw)
    hx, hy = 0.5 * size[0], 0.5 * size[1]
    local = np.array([[-hx, -hy], [hx, -hy], [hx, hy], [-hx, hy]])
    return local @ np.array([[c, s], [-s, c]]) + np.asarray(centre, dtype=float)[:2]


def footprint_penetration(
    a: ObjectSpec, pose_a: np.ndarray, b: ObjectSpec, pose_b: np.ndarray
) -> float:
    """Depth (m) by which two catalogue objects' footprints overlap (<= 0: apart).

    Args:
        a: The first object.
        pose_a: (3,) its world ``(x, y, theta)``.
        b: The second object.
        pose_b: (3,) its world ``(x, y, theta)``.
    """
    pa, pb = np.asarray(pose_a, dtype=float), np.asarray(pose_b, dtype=float)
    if a.shape == "circle" and b.shape == "circle":
        return float(a.radius + b.radius - math.hypot(*(pa[:2] - pb[:2])))
    if a.shape == "circle":
        return rect_disc_penetration(pb[:2], b.size, float(pb[2]), pa[:2], a.radius)
    if b.shape == "circle":
        return rect_disc_penetration(pa[:2], a.size, float(pa[2]), pb[:2], b.radius)
    return convex_penetration(
        _rect_corners(pa[:2], a.size, float(pa[2])), _rect_corners(pb[:2], b.size, float(pb[2]))
    )


def footprint_polygon(obj: ObjectSpec) -> np.ndarray | None:
    """Corners of a box footprint in the object frame, counter-clockwise.

    Returns:
        (4, 2) vertices (m), or ``None`` for a circle.
    """
    if obj.shape == "circle":
        return None
    hx, hy = 0.5 * obj.size[0], 0.5 * obj.size[1]
    return np.array([[-hx, -hy], [hx, -hy], [hx, hy], [-hx, hy]])


def footprint_support(obj: ObjectSpec, theta: float, direction: np.ndarray) -> float:
    """Extent of a footprint from its centre along a world direction (its support function).

    Args:
        obj: Catalogue object.
        theta: Object yaw in the world (rad).
        direction: (2,) unit vector in the world frame.

    Returns:
        max over footprint points p of ``direction . (p - centre)`` (m).
    """
    if obj.shape == "circle":
        return obj.radius
    c, s = math.cos(theta), math.sin(theta)
    ax = np.array([c, s])
    ay = np.array([-s, c])
    return 0.5 * (abs(direction @ ax) * obj.size[0] + abs(direction @ ay) * obj.size[1])


def friction_points(obj: ObjectSpec, n: int) -> np.ndarray:
    """Support points of a uniform-pressure footprint, in the object frame.

    The footprint is cut into an n x n grid of equal cells over its bounding box; each cell
    whose centre lies inside the footprint contributes its centre. Each point carries an equal
    share of the normal load, which discretises a uniform pressure distribution (the limit
    surface of Goyal et al.).

    Args:
        obj: Catalogue object.
        n: Grid cells per axis (a positive integer).

    Returns:
        (P, 2) points (m), P <= n * n.

    Raises:
        InputError: If `n` is not a positive integer.
    """
    n = check_count("n", n)
    hx, hy = 0.5 * obj.size[0], 0.5 * obj.size[1]
    u = (np.arange(n) + 0.5) / n * 2.0 - 1.0
    gx, gy = np.meshgrid(u * hx, u * hy)
    pts = np.stack([gx.ravel(), gy.ravel()], axis=-1)
    if obj.shape == "circle":
        pts = pts[np.hypot(pts[:, 0], pts[:, 1]) <= obj.radius]
        if len(pts) == 0:
            pts = np.zeros((1, 2))
    return pts


def to_push_frame(xy: np.ndarray, origin: np.ndarray, push_yaw: float) -> np.ndarray:
    """Express world points in the pushing frame.

    Args:
        xy: (..., 2) world positions (m).
        origin: (2,) world position of the pushing-frame origin (the hand's start).
        push_yaw: World yaw of z_p (rad).

    Returns:
        (..., 2) coordinates ``(y_p, z_p)`` (m).
    """
    c, s = math.cos(push_yaw), math.sin(push_yaw)
    rel = np.asarray(xy) - origin
    z = rel[..., 0] * c + rel[..., 1] * s
    y = -rel[..., 0] * s + rel[..., 1] * c
    return np.stack([y, z], axis=-1)


def push_frame_effect(before: np.ndarray, after: np.ndarray, push_yaw: float) -> np.ndarray:
    """The effect of a push on objects, in the pushing frame.

    Args:
        before: (K, 3) world ``(x, y, theta)`` before the push (theta unwrapped).
        after: (K, 3) world ``(x, y, theta)`` after the push (theta unwrapped, so turns of more
            than pi are kept).
        push_yaw: World yaw of z_p (rad).

    Returns:
        (K, 3) ``(Delta y_p, Delta z_p, Delta theta_p)`` in metres and radians.

    Raises:
        InputError: If `before` or `after` is not a finite (K, 3) array (the same K), or
            `push_yaw` is not finite: a NaN pose would otherwise give a NaN effect silently.
    """
    before, after = np.asarray(before, dtype=float), np.asarray(after, dtype=float)
    check_shape("before", before, (None, 3))
    check_shape("after", after, (before.shape[0], 3))
    check_finite("before", before)
    check_finite("after", after)
    check_finite("push_yaw", push_yaw)
    d = to_push_frame(after[:, :2], before[:, :2], push_yaw)
    return np.concatenate([d, (after[:, 2] - before[:, 2])[:, None]], axis=-1)
