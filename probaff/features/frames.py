"""Point clouds in the pushing frame, vectorised over pushes.

Pushing frame: origin at the hand's start pose (at push height above the table), z_p along the
push, y_p to its left, x_p pointing down into the table (right-handed).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from probaff._checks import as_float_array, check_number, check_shape
from probaff.errors import InputError

__all__ = ["directions_to_push_frame", "points_to_push_frame"]


def _frame_inputs(name: str, x: Any, yaw: Any) -> tuple[np.ndarray, np.ndarray]:
    """`x` as (N, ..., 3) floats and `yaw` as (N,) floats, or `InputError` naming either."""
    arr = as_float_array(name, x)
    if arr.ndim < 2 or arr.shape[-1] != 3:
        raise InputError(
            f"{name} must be an (N, ..., 3) array of world xyz per push, got shape {arr.shape}."
        )
    yaws = as_float_array("yaw", yaw)
    check_shape("yaw", yaws, (arr.shape[0],))
    return arr, yaws


def _axes(yaw: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    d = np.stack([np.cos(yaw), np.sin(yaw)], -1)  # z_p in the world, (N, 2)
    left = np.stack([-d[:, 1], d[:, 0]], -1)  # y_p in the world, (N, 2)
    return d, left


def points_to_push_frame(
    points: np.ndarray, origin: np.ndarray, yaw: np.ndarray, height: float
) -> np.ndarray:
    """World points to pushing-frame coordinates.

    Args:
        points: (N, ..., 3) world points of push n.
        origin: (N, 2) world xy of each pushing-frame origin.
        yaw: (N,) world yaw of each z_p.
        height: Height of the origin above the table (m).

    Returns:
        (N, ..., 3) coordinates ``(x_p, y_p, z_p)``.

    Raises:
        InputError: For arrays that are not numbers or not of these shapes, or a `height`
            that is not a finite number.
    """
    points, yaw = _frame_inputs("points", points, yaw)
    origin = as_float_array("origin", origin)
    check_shape("origin", origin, (points.shape[0], 2))
    height = check_number("height", height, unit="m")
    d, left = _axes(yaw)
    extra = (slice(None),) + (None,) * (points.ndim - 2)
    rel = points[..., :2] - origin[extra]
    z = rel[..., 0] * d[extra][..., 0] + rel[..., 1] * d[extra][..., 1]
    y = rel[..., 0] * left[extra][..., 0] + rel[..., 1] * left[extra][..., 1]
    return np.stack([height - points[..., 2], y, z], -1)


def directions_to_push_frame(vectors: np.ndarray, yaw: np.ndarray) -> np.ndarray:
    """World direction vectors (e.g. normals) to the pushing frame.

    Args:
        vectors: (N, ..., 3) world vectors.
        yaw: (N,) world yaw of each z_p.

    Returns:
        (N, ..., 3) components ``(x_p, y_p, z_p)``.

    Raises:
        InputError: For arrays that are not numbers or not of these shapes.
    """
    vectors, yaw = _frame_inputs("vectors", vectors, yaw)
    d, left = _axes(yaw)
    extra = (slice(None),) + (None,) * (vectors.ndim - 2)
    z = vectors[..., 0] * d[extra][..., 0] + vectors[..., 1] * d[extra][..., 1]
    y = vectors[..., 0] * left[extra][..., 0] + vectors[..., 1] * left[extra][..., 1]
    return np.stack([-vectors[..., 2], y, z], -1)
