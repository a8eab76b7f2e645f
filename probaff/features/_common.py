"""Pieces shared by the chapter 4 and chapter 5 feature sets."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from probaff._checks import check_count, check_finite
from probaff.data.queries import PushInputs
from probaff.errors import InputError
from probaff.features.frames import directions_to_push_frame, points_to_push_frame

__all__ = ["FINGER_LENGTH", "PushClouds", "chunked", "meta_float", "principal_yaw"]

FINGER_LENGTH = 0.08  # m; fingers reach from push height up to this far above it


def meta_float(ds: PushInputs, key: str) -> float:
    """A numeric dataset metadata entry, with a clear error if it is missing."""
    if key not in ds.meta:
        raise InputError(
            f"dataset metadata lacks {key!r}; regenerate it with this version of probaff."
        )
    return float(ds.meta[key])


class PushClouds:
    """The object clouds of a slice of pushes, in each push's pushing frame.

    Attributes:
        points: (n, K, P, 3) pushing-frame ``(x_p, y_p, z_p)``.
        normals: (n, K, P, 3) pushing-frame normals.
        height: (n, K, P) height of each point above the table (m).
        distance: (n,) push distance d_p.
    """

    def __init__(self, ds: PushInputs, rows: slice) -> None:
        pts = ds["cloud_points"][rows].astype(np.float64)
        nrm = ds["cloud_normals"][rows].astype(np.float64)
        check_finite("cloud_points", pts)
        yaw = ds["push_yaw"][rows]
        h = meta_float(ds, "push_height")
        self.points = points_to_push_frame(pts, ds["push_origin"][rows], yaw, h)
        self.normals = directions_to_push_frame(nrm, yaw)
        self.height = pts[..., 2]
        self.distance = ds["push_distance"][rows]


def chunked(
    ds: PushInputs, dim: int, fn: Callable[[PushClouds], np.ndarray], chunk: int = 1024
) -> np.ndarray:
    """Apply `fn` to consecutive chunks of pushes and stack the (n, dim) results.

    Args:
        ds: A push dataset of N pushes.
        dim: Columns `fn` returns per push.
        fn: Maps the clouds of a chunk of n pushes to an (n, dim) array.
        chunk: Pushes per chunk (a positive integer).

    Returns:
        (N, dim) the stacked results.

    Raises:
        InputError: For an empty dataset or a `chunk` that is not a positive integer.
    """
    chunk = check_count("chunk", chunk)
    if len(ds) == 0:
        raise InputError("the dataset has no pushes; features need at least one.")
    out = np.empty((len(ds), dim))
    for start in range(0, len(ds), chunk):
        rows = slice(start, min(start + chunk, len(ds)))
        out[rows] = fn(PushClouds(ds, rows))
    return out


def principal_yaw(y: np.ndarray, z: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """Angle of the principal axis of 2-D points, relative to z_p, in (-pi/2, pi/2].

    Args:
        y: (..., P) y_p coordinates.
        z: (..., P) z_p coordinates.
        mask: (..., P) points to use.

    Returns:
        (...,) angle (rad) of the major axis from z_p towards y_p; 0 where fewer than 3 points.
    """
    w = mask.astype(float)
    n = w.sum(-1)
    safe = np.maximum(n, 1.0)
    my, mz = (w * y).sum(-1) / safe, (w * z).sum(-1) / safe
    dy, dz = (y - my[..., None]) * w, (z - mz[..., None]) * w
    syy, szz, syz = (dy * dy).sum(-1), (dz * dz).sum(-1), (dy * dz).sum(-1)
    ang = 0.5 * np.arctan2(2 * syz, szz - syy)
    ang = np.where(ang <= -np.pi / 2, ang + np.pi, ang)
    return np.where(n >= 3, ang, 0.0)
