"""Simulated depth sensing: point clouds of the objects and the table from their known geometry.

Points are sampled uniformly by area on the surfaces a sensor above the table sees (object tops
and sides, and the uncovered table top), with isotropic Gaussian noise. All clouds are in the
world frame (table centre on its surface, z up).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from probaff._checks import check_count, check_positive
from probaff.sim.config import ObjectSpec

__all__ = ["Scan", "object_cloud", "scan_scene", "table_cloud"]


@dataclass(frozen=True)
class Scan:
    """A simulated scan.

    Attributes:
        object_points: (K, P, 3) world points of each object.
        object_normals: (K, P, 3) unit outward normals of those points (noise-free).
        table_points: (Q, 3) world points of the visible table top.
    """

    object_points: np.ndarray
    object_normals: np.ndarray
    table_points: np.ndarray


def _box_surface(
    obj: ObjectSpec, n: int, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray]:
    lx, ly, h = obj.size[0], obj.size[1], obj.height
    areas = np.array([lx * ly, ly * h, ly * h, lx * h, lx * h])
    face = rng.choice(5, size=n, p=areas / areas.sum())
    u, v = rng.random(n), rng.random(n)
    pts = np.empty((n, 3))
    nrm = np.zeros((n, 3))
    top = face == 0
    pts[top] = np.stack([(u[top] - 0.5) * lx, (v[top] - 0.5) * ly, np.full(top.sum(), h)], -1)
    nrm[top, 2] = 1.0
    for f, axis, sign in ((1, 0, 1.0), (2, 0, -1.0), (3, 1, 1.0), (4, 1, -1.0)):
        m = face == f
        other = 1 - axis
        extent = (lx, ly)
        p = np.zeros((m.sum(), 3))
        p[:, axis] = sign * 0.5 * extent[axis]
        p[:, other] = (u[m] - 0.5) * extent[other]
        p[:, 2] = v[m] * h
        pts[m] = p
        nrm[m, axis] = sign
    return pts, nrm


def _circle_surface(
    obj: ObjectSpec, n: int, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray]:
    r, h = obj.radius, obj.height
    top_area, side_area = math.pi * r * r, 2 * math.pi * r * h
    top = rng.random(n) < top_area / (top_area + side_area)
    a = rng.uniform(-math.pi, math.pi, n)
    rad = np.where(top, r * np.sqrt(rng.random(n)), r)
    z = np.where(top, h, rng.random(n) * h)
    pts = np.stack([rad * np.cos(a), rad * np.sin(a), z], -1)
    nrm = np.where(
        top[:, None], np.array([0.0, 0.0, 1.0]), np.stack([np.cos(a), np.sin(a), np.zeros(n)], -1)
    )
    return pts, nrm


def object_cloud(
    obj: ObjectSpec, pose: np.ndarray, n_points: int, noise: float, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray]:
    """Sample a point cloud of one object.

    Args:
        obj: Catalogue object.
        pose: (3,) world ``(x, y, theta)``.
        n_points: Number of points P (a positive integer).
        noise: Standard deviation of the Gaussian position noise (m).
        rng: Source of randomness.

    Returns:
        ``(points, normals)``, each (P, 3) in the world frame.

    Raises:
        InputError: If `n_points` is not a positive integer or `noise` is negative.
    """
    n_points = check_count("n_points", n_points)
    check_positive("noise", noise, allow_zero=True)
    sampler = _circle_surface if obj.shape == "circle" else _box_surface
    pts, nrm = sampler(obj, n_points, rng)
    c, s = math.cos(pose[2]), math.sin(pose[2])
    R = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    pts = pts @ R.T + np.array([pose[0], pose[1], 0.0])
    return pts + rng.normal(0.0, noise, pts.shape) if noise > 0 else pts, nrm @ R.T


def _inside(obj: ObjectSpec, pose: np.ndarray, xy: np.ndarray) -> np.ndarray:
    c, s = math.cos(pose[2]), math.sin(pose[2])
    rel = xy - pose[:2]
    lx = rel[:, 0] * c + rel[:, 1] * s
    ly = -rel[:, 0] * s + rel[:, 1] * c
    if obj.shape == "circle":
        return np.hypot(lx, ly) <= obj.radius
    return (np.abs(lx) <= 0.5 * obj.size[0]) & (np.abs(ly) <= 0.5 * obj.size[1])


def table_cloud(
    table_size: tuple[float, float],
    spacing: float,
    noise: float,
    rng: np.random.Generator,
    occluders: list[tuple[ObjectSpec, np.ndarray]] = (),  # type: ignore[assignment]
) -> np.ndarray:
    """Sample the visible table top on a jittered grid.

    Args:
        table_size: Table extent along world x and y (m), centred at the origin.
        spacing: Grid spacing (m).
        noise: Standard deviation of the Gaussian position noise (m).
        rng: Source of randomness.
        occluders: ``(object, pose (3,))`` pairs whose footprints hide the table.

    Returns:
        (Q, 3) world points.
    """
    check_positive("spacing", spacing)
    check_positive("noise", noise, allow_zero=True)
    xs = np.arange(-0.5 * table_size[0] + 0.5 * spacing, 0.5 * table_size[0], spacing)
    ys = np.arange(-0.5 * table_size[1] + 0.5 * spacing, 0.5 * table_size[1], spacing)
    gx, gy = np.meshgrid(xs, ys)
    xy = np.stack([gx.ravel(), gy.ravel()], -1)
    keep = np.ones(len(xy), dtype=bool)
    for obj, pose in occluders:
        keep &= ~_inside(obj, np.asarray(pose, dtype=float), xy)
    pts = np.concatenate([xy[keep], np.zeros((keep.sum(), 1))], -1)
    return pts + rng.normal(0.0, noise, pts.shape) if noise > 0 else pts


def scan_scene(
    objects: tuple[ObjectSpec, ...],
    poses: np.ndarray,
    table_size: tuple[float, float],
    rng: np.random.Generator,
    n_points: int = 256,
    noise: float = 0.002,
    table_spacing: float = 0.02,
) -> Scan:
    """Scan a whole scene: every object and the uncovered table.

    Args:
        objects: K catalogue objects.
        poses: (K, 3) world ``(x, y, theta)``.
        table_size: Table extent (m).
        rng: Source of randomness.
        n_points: Points per object P (a positive integer).
        noise: Position noise standard deviation (m).
        table_spacing: Grid spacing of the table cloud (m).

    Returns:
        The scan.

    Raises:
        InputError: If `n_points` is not a positive integer, or `noise` or `table_spacing` is
            out of range.
    """
    n_points = check_count("n_points", n_points)
    clouds = [object_cloud(o, p, n_points, noise, rng) for o, p in zip(objects, poses, strict=True)]
    return Scan(
        object_points=np.stack([c[0] for c in clouds]),
        object_normals=np.stack([c[1] for c in clouds]),
        table_points=table_cloud(
            table_size, table_spacing, noise, rng, list(zip(objects, poses, strict=True))
        ),
    )
