"""Simulated depth sensing: point clouds of the objects and the table from their known geometry.

Points are sampled uniformly by area on the surfaces a sensor above the table sees (object tops
and sides, and the uncovered table top), with isotropic Gaussian noise. All clouds are in the
world frame (table centre on its surface, z up).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from probaff._checks import check_count, check_finite, check_positive, check_shape
from probaff.errors import InputError
from probaff.sim.inputs import check_rng, floats
from probaff.sim.specs import ObjectSpec

__all__ = ["Scan", "object_cloud", "scan_scene", "table_cloud"]


def _check_object(name: str, obj: object) -> ObjectSpec:
    if not isinstance(obj, ObjectSpec):
        raise InputError(
            f"{name} must be a catalogue ObjectSpec (load_catalogue()[name]), got "
            f"{type(obj).__name__}."
        )
    return obj


def _check_table(table_size: object) -> tuple[float, float]:
    size = floats("table_size", table_size)
    check_shape("table_size", size, (2,))
    for i in range(2):
        check_positive(f"table_size[{i}]", float(size[i]))
    return float(size[0]), float(size[1])


def _check_noise(noise: object) -> float:
    if isinstance(noise, (bool, str, bytes)):
        raise InputError(f"noise must be a finite number >= 0, got {noise!r}.")
    check_positive("noise", noise, allow_zero=True)  # type: ignore[arg-type]
    return float(noise)  # type: ignore[arg-type]


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
        InputError: If `obj` is not an `ObjectSpec`, `pose` not a finite (3,), `n_points` not
            a positive integer, `noise` negative or `rng` not a `numpy.random.Generator`.
    """
    obj = _check_object("obj", obj)
    pose = floats("pose", pose)
    check_shape("pose", pose, (3,))
    check_finite("pose", pose)
    n_points = check_count("n_points", n_points)
    noise = _check_noise(noise)
    rng = check_rng(rng)
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

    Raises:
        InputError: For a table size that is not two numbers > 0, a spacing that is not > 0,
            a negative noise, an `rng` that is not a `numpy.random.Generator`, or an occluder
            that is not an ``(ObjectSpec, finite (3,) pose)`` pair.
    """
    table_size = _check_table(table_size)
    if isinstance(spacing, (bool, str, bytes)):
        raise InputError(f"spacing must be a finite number > 0, got {spacing!r}.")
    check_positive("spacing", spacing)
    noise = _check_noise(noise)
    rng = check_rng(rng)
    checked = []
    for i, item in enumerate(occluders):
        if not isinstance(item, (tuple, list)) or len(item) != 2:
            raise InputError(f"occluders[{i}] must be an (ObjectSpec, pose) pair, got {item!r}.")
        pose = floats(f"occluders[{i}] pose", item[1])
        check_shape(f"occluders[{i}] pose", pose, (3,))
        check_finite(f"occluders[{i}] pose", pose)
        checked.append((_check_object(f"occluders[{i}] object", item[0]), pose))
    xs = np.arange(-0.5 * table_size[0] + 0.5 * spacing, 0.5 * table_size[0], spacing)
    ys = np.arange(-0.5 * table_size[1] + 0.5 * spacing, 0.5 * table_size[1], spacing)
    gx, gy = np.meshgrid(xs, ys)
    xy = np.stack([gx.ravel(), gy.ravel()], -1)
    keep = np.ones(len(xy), dtype=bool)
    for obj, pose in checked:
        keep &= ~_inside(obj, pose, xy)
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
        InputError: If `objects` is not a non-empty list of `ObjectSpec`, `poses` not a finite
            (K, 3) array, `n_points` not a positive integer, or `noise`, `table_size`,
            `table_spacing` or `rng` is out of range or of the wrong type.
    """
    if isinstance(objects, ObjectSpec) or not isinstance(objects, (tuple, list)) or not objects:
        raise InputError(
            f"objects must be a non-empty list of catalogue ObjectSpec, got {objects!r}."
        )
    objects = tuple(_check_object(f"objects[{k}]", o) for k, o in enumerate(objects))
    poses = floats("poses", poses)
    check_shape("poses", poses, (len(objects), 3))
    check_finite("poses", poses)
    table_size = _check_table(table_size)
    n_points = check_count("n_points", n_points)
    clouds = [object_cloud(o, p, n_points, noise, rng) for o, p in zip(objects, poses, strict=True)]
    return Scan(
        object_points=np.stack([c[0] for c in clouds]),
        object_normals=np.stack([c[1] for c in clouds]),
        table_points=table_cloud(
            table_size, table_spacing, noise, rng, list(zip(objects, poses, strict=True))
        ),
    )
