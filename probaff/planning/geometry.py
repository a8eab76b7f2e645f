"""Rectangular footprints on the table: corners, overlaps and the chord a line cuts.

Frames: poses are world ``(x, y, theta)`` (the table's frame, z up); a footprint of extent
``(a, b)`` spans ``a`` along the object's own x axis and ``b`` along its y axis, centred on the
pose. A circle is taken as its bounding square (extent ``(2 r, 2 r)``, as `ObjectSpec.size`).

Covered by tests/planning/test_planning_geometry.py.
"""

from __future__ import annotations

import math

import numpy as np

from probaff._checks import as_float_vectors, check_number
from probaff.errors import InputError

__all__ = ["box_corners", "boxes_overlap", "chord_at"]


def _poses(name: str, poses: object) -> np.ndarray:
    """`poses` as finite ``(..., 3)`` float64 ``(x, y, theta)``, or raise naming `name`."""
    return as_float_vectors(name, poses, 3, "world (x, y, theta) poses")


def _extent(name: str, size: object, grow: float = 0.0) -> tuple[float, float]:
    """`size` as two finite extents > 0 (m), each grown by ``2 grow``, or raise naming `name`."""
    arr = as_float_vectors(name, size, 2, "extents (a, b) in metres")
    if arr.shape != (2,) or not (arr > 0).all():
        raise InputError(f"{name} must be two extents (a, b) > 0 (m), got {size!r:.80}.")
    return float(arr[0]) + 2 * grow, float(arr[1]) + 2 * grow


def _corners(poses: np.ndarray, extent: tuple[float, float]) -> np.ndarray:
    """`box_corners` of checked ``(..., 3)`` poses and extent."""
    hx, hy = 0.5 * extent[0], 0.5 * extent[1]
    local = np.array([[-hx, -hy], [hx, -hy], [hx, hy], [-hx, hy]])
    c, s = np.cos(poses[..., 2])[..., None], np.sin(poses[..., 2])[..., None]
    x = poses[..., 0, None] + c * local[:, 0] - s * local[:, 1]
    y = poses[..., 1, None] + s * local[:, 0] + c * local[:, 1]
    return np.stack([x, y], axis=-1)


def box_corners(poses: np.ndarray, size: tuple[float, float]) -> np.ndarray:
    """Corners of rectangular footprints in the world.

    Args:
        poses: (..., 3) world ``(x, y, theta)``.
        size: Extent ``(a, b)`` along the object's own x and y (m).

    Returns:
        (..., 4, 2) world corners, counter-clockwise.

    Raises:
        InputError: For poses that are not finite ``(..., 3)`` numbers, or a `size` that is
            not two extents > 0.
    """
    return _corners(_poses("poses", poses), _extent("size", size))


def boxes_overlap(
    poses_a: np.ndarray,
    size_a: tuple[float, float],
    pose_b: np.ndarray,
    size_b: tuple[float, float],
    margin: float = 0.0,
) -> np.ndarray:
    """Whether rectangles overlap, by the separating-axis test.

    Args:
        poses_a: (..., 3) world poses of the first rectangles.
        size_a: Their extent (m).
        pose_b: (3,) world pose of the second rectangle.
        size_b: Its extent (m).
        margin: Grow both by this much (m) on every side before testing.

    Returns:
        (...,) bool.

    Raises:
        InputError: For poses that are not finite ``(..., 3)`` numbers (`pose_b` one pose),
            sizes that are not two extents > 0, or a `margin` that is not a finite number.
    """
    pa_, pb_ = _poses("poses_a", poses_a), _poses("pose_b", pose_b)
    if pb_.shape != (3,):
        raise InputError(f"pose_b must be one (x, y, theta) pose, got shape {pb_.shape}.")
    grow = check_number("margin", margin, unit="m")
    ca = _corners(pa_, _extent("size_a", size_a, grow))
    cb = _corners(pb_, _extent("size_b", size_b, grow))
    th_a = pa_[..., 2]
    th_b = float(pb_[2])
    axes = [
        np.stack([np.cos(th_a), np.sin(th_a)], -1),
        np.stack([-np.sin(th_a), np.cos(th_a)], -1),
        np.broadcast_to(np.array([math.cos(th_b), math.sin(th_b)]), (*th_a.shape, 2)),
        np.broadcast_to(np.array([-math.sin(th_b), math.cos(th_b)]), (*th_a.shape, 2)),
    ]
    separated = np.zeros(th_a.shape, dtype=bool)
    for ax in axes:
        pa = (ca * ax[..., None, :]).sum(-1)  # (..., 4)
        pb = (cb * ax[..., None, :]).sum(-1)
        separated |= (pa.max(-1) < pb.min(-1)) | (pb.max(-1) < pa.min(-1))
    return ~separated


def chord_at(poses: np.ndarray, size: tuple[float, float], line_x: float) -> np.ndarray:
    """Length of the chord that the line ``x = line_x`` cuts from rectangular footprints.

    Args:
        poses: (..., 3) world poses.
        size: Extent of the rectangle (m).
        line_x: World x of the line.

    Returns:
        (...,) chord length (m); 0 where the line misses the footprint.

    Raises:
        InputError: As `box_corners`, or for a `line_x` that is not a finite number.
    """
    corners = box_corners(poses, size)
    line_x = check_number("line_x", line_x, unit="m")
    a, b = corners, np.roll(corners, -1, axis=-2)  # the four edges a -> b
    dx = b[..., 0] - a[..., 0]
    crosses = (a[..., 0] - line_x) * (b[..., 0] - line_x) <= 0
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(np.abs(dx) > 1e-12, (line_x - a[..., 0]) / dx, 0.0)
    y = a[..., 1] + t * (b[..., 1] - a[..., 1])
    hi = np.where(crosses, y, -np.inf).max(-1)
    lo = np.where(crosses, y, np.inf).min(-1)
    return np.where(np.isfinite(hi) & np.isfinite(lo), np.maximum(hi - lo, 0.0), 0.0)
