"""Point clouds in the pushing frame, vectorised over pushes.

Pushing frame: origin at the hand's start pose (at push height above the table), z_p along the
push, y_p to its left, x_p pointing down into the table (right-handed).
"""

from __future__ import annotations

import numpy as np

__all__ = ["directions_to_push_frame", "points_to_push_frame"]


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
    """
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
    """
    d, left = _axes(yaw)
    extra = (slice(None),) + (None,) * (vectors.ndim - 2)
    z = vectors[..., 0] * d[extra][..., 0] + vectors[..., 1] * d[extra][..., 1]
    y = vectors[..., 0] * left[extra][..., 0] + vectors[..., 1] * left[extra][..., 1]
    return np.stack([-vectors[..., 2], y, z], -1)
