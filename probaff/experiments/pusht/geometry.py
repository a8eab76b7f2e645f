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

Which T. `TeeGeometry` holds one T: its two boxes, its centre of gravity and its moment of
inertia. `GYM_TEE` is gym-pusht's, from its source (the constants above); `TeeGeometry
.from_shape` builds one from an outline perceived in the images (`probaff.experiments.pusht
.template.TeeShape`), of uniform density, since a camera sees no mass. The functions below
take the T as their ``tee`` argument, `GYM_TEE` by default.

Input. The functions take real numbers of the shapes their docstrings give and raise
`InputError` naming the argument otherwise; NaN passes through, since a pose the camera did
not see is NaN and its cost or distance is then NaN too.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from probaff._checks import as_float_array, as_float_vectors
from probaff.errors import InputError

__all__ = [
    "AGENT_RADIUS",
    "ARENA",
    "COG",
    "GOAL_ORIGIN_POSE",
    "GYM_TEE",
    "INERTIA",
    "KEYPOINTS",
    "OUTLINE",
    "PERIMETER",
    "PX",
    "RECTS",
    "TeeGeometry",
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
GOAL_ORIGIN_POSE = np.array([256.0, 256.0, math.pi / 4])
"""The goal's body-origin pose (px, px, rad)."""


@dataclass(frozen=True, eq=False)
class TeeGeometry:
    """One T: a bar and a stem, its centre of gravity and moment of inertia (px).

    The T frame (the body's) has its origin at the middle of the bar's outer edge and its y
    axis along the stem; the block frame is the T frame moved to the centre of gravity.

    Attributes:
        rects: (2, 4) the bar and the stem ``(x0, y0, x1, y1)`` in the block frame.
        cog: (2,) the centre of gravity in the T frame.
        inertia: Moment of inertia about the centre of gravity per unit mass (px^2).
        outline: (8, 2) the T's corners in the block frame, counter-clockwise.
        perimeter: Length of the outline.
        radius: Root mean square distance of the corners from the centre of gravity.
    """

    rects: np.ndarray
    cog: np.ndarray
    inertia: float
    outline: np.ndarray = field(init=False)
    perimeter: float = field(init=False)
    radius: float = field(init=False)
    _edges: np.ndarray = field(init=False, repr=False)
    _lengths: np.ndarray = field(init=False, repr=False)
    _starts: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        (bx0, by0, bx1, by1), (sx0, sy0, sx1, sy1) = self.rects
        outline = np.array(
            [
                [bx0, by0],
                [bx1, by0],
                [bx1, by1],
                [sx1, sy0],
                [sx1, sy1],
                [sx0, sy1],
                [sx0, sy0],
                [bx0, by1],
            ],
            dtype=float,
        )
        edges = np.roll(outline, -1, axis=0) - outline
        lengths = np.linalg.norm(edges, axis=1)
        values: dict[str, Any] = {
            "outline": outline,
            "_edges": edges,
            "_lengths": lengths,
            "_starts": np.r_[0.0, np.cumsum(lengths)[:-1]],
            "perimeter": float(lengths.sum()),
            "radius": float(np.sqrt((outline**2).sum(axis=1).mean())),
        }
        for name, value in values.items():
            object.__setattr__(self, name, value)

    @classmethod
    def from_lengths(
        cls,
        bar_length: float,
        bar_width: float,
        stem_width: float,
        stem_length: float,
        *,
        cog: np.ndarray | None = None,
        inertia: float | None = None,
    ) -> TeeGeometry:
        """A T of the given bar and stem (px); of uniform density unless `cog`, `inertia` given.

        Args:
            bar_length: The bar's length, across the stem.
            bar_width: The bar's width, along the stem.
            stem_width: The stem's width.
            stem_length: The stem's length below the bar.
            cog: (2,) the centre of gravity in the T frame; the centre of area by default.
            inertia: Moment of inertia per unit mass about it; a uniform lamina's by default.
        """
        boxes = np.array(
            [
                [-bar_length / 2, 0.0, bar_length / 2, bar_width],
                [-stem_width / 2, bar_width, stem_width / 2, bar_width + stem_length],
            ]
        )
        areas = (boxes[:, 2] - boxes[:, 0]) * (boxes[:, 3] - boxes[:, 1])
        centres = np.column_stack([boxes[:, 0] + boxes[:, 2], boxes[:, 1] + boxes[:, 3]]) / 2
        at = centres.T @ areas / areas.sum() if cog is None else np.asarray(cog, dtype=float)
        if inertia is None:
            own = ((boxes[:, 2] - boxes[:, 0]) ** 2 + (boxes[:, 3] - boxes[:, 1]) ** 2) / 12
            shift = ((centres - at) ** 2).sum(axis=1)
            inertia = float((areas * (own + shift)).sum() / areas.sum())
        return cls(boxes - np.r_[at, at], at, float(inertia))

    @classmethod
    def from_shape(cls, shape: Any) -> TeeGeometry:
        """The T of a perceived outline (`TeeShape`), of uniform density (a camera sees no mass)."""
        return cls.from_lengths(
            float(shape.bar_length),
            float(shape.bar_width),
            float(shape.stem_width),
            float(shape.stem_length),
        )


GYM_TEE = TeeGeometry.from_lengths(
    120.0, 30.0, 30.0, 90.0, cog=np.array([0.0, 45.0]), inertia=3000.0
)
"""gym-pusht's T, from its source: a bar ``[-60, 60] x [0, 30]`` and a stem ``[-15, 15] x
[30, 120]`` (body frame), each shape of mass 1, so the centre of gravity is the mean of their
centres, ``(0, 45)``; gym-pusht adds the bar's moment about the body origin twice,
``2 * ((120^2 + 30^2) / 12 + 15^2) = 3000``."""
COG = GYM_TEE.cog
"""gym-pusht's centre of gravity in its body frame (px): the mean of its two boxes' centres."""
INERTIA = GYM_TEE.inertia
"""gym-pusht's moment of inertia about its centre of gravity (px^2, mass 1)."""
RECTS = GYM_TEE.rects
"""gym-pusht's two boxes ``(x0, y0, x1, y1)`` in the block frame (centre of gravity at 0)."""
OUTLINE = GYM_TEE.outline
"""gym-pusht's T outline in the block frame, counter-clockwise (px)."""
KEYPOINTS = OUTLINE
"""The points whose distance to the goal's scores a pose (`keypoint_cost`)."""
PERIMETER = GYM_TEE.perimeter
"""Length of gym-pusht's T outline (480 px)."""


def _rot(theta: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
    return np.cos(theta), np.sin(theta)


def _poses(name: str, pose: object) -> np.ndarray:
    """`pose` as ``(..., 3)`` float64 ``(x, y, angle)``, or raise naming `name`."""
    return as_float_vectors(name, pose, 3, "(x, y, angle) poses", finite=False)


def _points(name: str, points: object) -> np.ndarray:
    """`points` as ``(..., 2)`` float64 points, or raise naming `name`."""
    return as_float_vectors(name, points, 2, "(x, y) points", finite=False)


def _to_world(pose: np.ndarray, points: np.ndarray) -> np.ndarray:
    """`to_world` of checked arrays."""
    c, s = _rot(pose[..., 2:3])
    px, py = points[..., 0], points[..., 1]
    return np.stack([pose[..., 0:1] + c * px - s * py, pose[..., 1:2] + s * px + c * py], axis=-1)


def cog_pose(origin: np.ndarray, tee: TeeGeometry = GYM_TEE) -> np.ndarray:
    """Centre-of-gravity poses from body-origin (T frame) poses.

    Args:
        origin: (..., 3) body-origin ``(x, y, angle)`` (px, px, rad).
        tee: The T.

    Returns:
        (..., 3) ``(x, y, angle)`` of the centre of gravity (the angle unchanged).

    Raises:
        InputError: For anything but ``(..., 3)`` numbers (NaN passes through).
    """
    origin = _poses("origin", origin)
    cog = tee.cog
    c, s = _rot(origin[..., 2])
    x = origin[..., 0] + c * cog[0] - s * cog[1]
    y = origin[..., 1] + s * cog[0] + c * cog[1]
    return np.stack([x, y, origin[..., 2]], axis=-1)


def origin_pose(pose: np.ndarray, tee: TeeGeometry = GYM_TEE) -> np.ndarray:
    """Body-origin poses from centre-of-gravity poses (the inverse of `cog_pose`).

    Args:
        pose: (..., 3) centre-of-gravity ``(x, y, angle)``.
        tee: The T.

    Returns:
        (..., 3) body-origin ``(x, y, angle)``.

    Raises:
        InputError: For anything but ``(..., 3)`` numbers (NaN passes through).
    """
    pose = _poses("pose", pose)
    cog = tee.cog
    c, s = _rot(pose[..., 2])
    x = pose[..., 0] - (c * cog[0] - s * cog[1])
    y = pose[..., 1] - (s * cog[0] + c * cog[1])
    return np.stack([x, y, pose[..., 2]], axis=-1)


def to_world(pose: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Block-frame points in the world.

    Args:
        pose: (..., 3) centre-of-gravity poses.
        points: (..., P, 2) block-frame points (broadcast against `pose`'s batch).

    Returns:
        (..., P, 2) world points.

    Raises:
        InputError: For a `pose` or `points` that are not ``(..., 3)`` or ``(..., 2)``
            numbers.
    """
    return _to_world(_poses("pose", pose), _points("points", points))


def to_block(pose: np.ndarray, points: np.ndarray) -> np.ndarray:
    """World points in the block frame of `pose` (the inverse of `to_world`).

    Args:
        pose: (3,) a centre-of-gravity pose.
        points: (P, 2) world points.

    Returns:
        (P, 2) block-frame points.

    Raises:
        InputError: For a `pose` that is not one ``(x, y, angle)``, or `points` that are not
            ``(..., 2)`` numbers.
    """
    pose = _poses("pose", pose).reshape(-1)
    if pose.shape != (3,):
        raise InputError(f"pose must be one (x, y, angle) pose, got {pose.size // 3} poses.")
    c, s = math.cos(pose[2]), math.sin(pose[2])
    d = _points("points", points) - pose[:2]
    return np.stack([c * d[..., 0] + s * d[..., 1], -s * d[..., 0] + c * d[..., 1]], axis=-1)


def contact_points(s: np.ndarray, tee: TeeGeometry = GYM_TEE) -> tuple[np.ndarray, np.ndarray]:
    """Points and outward normals on the T's outline at arc lengths `s`.

    Args:
        s: (K,) arc lengths along the T's outline from its first vertex (px, taken modulo
            its perimeter).
        tee: The T.

    Returns:
        ``(points, normals)``: (K, 2) block-frame points and (K, 2) unit outward normals.

    Raises:
        InputError: For `s` that is not a (K,) array of numbers.
    """
    starts, lengths, edges = tee._starts, tee._lengths, tee._edges
    arc = as_float_array("s", s)
    if arc.ndim != 1:
        raise InputError(f"s must be a (K,) array of arc lengths, got shape {arc.shape}.")
    s = np.mod(arc, tee.perimeter)
    edge = np.clip(np.searchsorted(starts, s, side="right") - 1, 0, len(starts) - 1)
    t = (s - starts[edge]) / lengths[edge]
    points = tee.outline[edge] + t[:, None] * edges[edge]
    d = edges[edge] / lengths[edge][:, None]
    normals = np.stack([d[:, 1], -d[:, 0]], axis=-1)  # counter-clockwise outline: right side
    return points, normals


def distance_to_tee(
    points: np.ndarray, tee: TeeGeometry = GYM_TEE
) -> tuple[np.ndarray, np.ndarray]:
    """Distance from block-frame points to the T, and the T's nearest points.

    Args:
        points: (..., 2) block-frame points.
        tee: The T.

    Returns:
        ``(distance, nearest)``: (...) distances (0 inside the T) and (..., 2) nearest points
        of the T.

    Raises:
        InputError: For anything but ``(..., 2)`` numbers.
    """
    p = _points("points", points)
    best_d = np.full(p.shape[:-1], np.inf)
    best_q = np.zeros_like(p)
    for x0, y0, x1, y1 in tee.rects:
        q = np.stack([np.clip(p[..., 0], x0, x1), np.clip(p[..., 1], y0, y1)], axis=-1)
        d = np.linalg.norm(p - q, axis=-1)
        closer = d < best_d
        best_d = np.where(closer, d, best_d)
        best_q = np.where(closer[..., None], q, best_q)
    return best_d, best_q


def keypoint_cost(pose: np.ndarray, goal: np.ndarray, tee: TeeGeometry = GYM_TEE) -> np.ndarray:
    """Mean distance (px) of the T's outline vertices at `pose` from theirs at `goal`.

    Args:
        pose: (..., 3) centre-of-gravity poses.
        goal: (3,) the goal's centre-of-gravity pose.
        tee: The T (its outline's corners are the keypoints).

    Returns:
        (...) mean vertex distances; 0 at the goal.

    Raises:
        InputError: For a `pose` or `goal` that is not ``(..., 3)`` numbers.
    """
    pose = _poses("pose", pose)
    keys = tee.outline
    at = _to_world(pose, np.broadcast_to(keys, (*pose.shape[:-1], *keys.shape)))
    target = _to_world(_poses("goal", goal), keys)
    return np.linalg.norm(at - target, axis=-1).mean(axis=-1)
