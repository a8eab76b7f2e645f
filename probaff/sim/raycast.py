"""Ray casting against upright boxes and vertical cylinders, vectorised over the rays.

The geometry under the depth camera (`probaff.sim.camera`): the slab method in each box's own
frame (yaw about world z), a quadratic for a cylinder's side plus a plane test for each of its
two caps, and the nearest hit over a `PrimitiveScene`, each primitive tested only on the rays
that enter the cone of its bounding sphere and are not yet stopped nearer. The ray parameter t
is the depth along the camera's optical axis when the directions have unit depth.

Covered by tests/sim/test_camera.py.
"""

from __future__ import annotations

import math

import numpy as np

from probaff.sim.primitives import PrimitiveScene

__all__ = ["box_hits", "cast_rays", "cylinder_hits", "rot_y", "rot_z", "rotvec"]


def rot_z(angle: float) -> np.ndarray:
    """(3, 3) rotation by `angle` (rad) about z."""
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def rot_y(angle: float) -> np.ndarray:
    """(3, 3) rotation by `angle` (rad) about y."""
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def rotvec(w: np.ndarray) -> np.ndarray:
    """(3, 3) rotation of the rotation vector `w` (3,) (rad), by Rodrigues' formula."""
    theta = float(np.linalg.norm(w))
    if theta < 1e-15:
        return np.eye(3)
    k = w / theta
    K = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + math.sin(theta) * K + (1.0 - math.cos(theta)) * (K @ K)


def box_hits(box: np.ndarray, o: np.ndarray, d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Entry of rays into one box, by the slab method in the box's own frame.

    Args:
        box: (7,) ``(cx, cy, cz, sx, sy, sz, yaw)``.
        o: (3,) world-frame ray origin, outside the box.
        d: (N, 3) world-frame ray directions; the ray parameter t is depth.

    Returns:
        ``(t (N,), normal (N, 3))``: the entry parameter (inf for a miss) and the world-frame
        outward normal of the face entered (rows of misses are arbitrary).
    """
    R = rot_z(float(box[6]))  # box -> world
    p = R.T @ (o - box[:3])
    db = d @ R  # (N, 3) directions in the box frame
    half = box[3:6] / 2.0
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / db
        t1 = (-half - p) * inv
        t2 = (half - p) * inv
    near = np.fmin(t1, t2)  # NaN (0 * inf, a ray in a face's plane) is ignored
    axis = near.argmax(axis=1)
    rows = np.arange(len(d))
    t_in = near[rows, axis]
    t_out = np.fmax(t1, t2).min(axis=1)
    hit = np.isfinite(t_in) & (t_in > 0.0) & (t_in <= t_out)
    n_box = np.zeros((len(d), 3))
    n_box[rows, axis] = -np.sign(db[rows, axis])
    return np.where(hit, t_in, np.inf), n_box @ R.T


def cylinder_hits(cyl: np.ndarray, o: np.ndarray, d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Entry of rays into one vertical cylinder: its side (a quadratic) or a cap (a plane).

    Args:
        cyl: (5,) ``(cx, cy, cz, radius, height)``.
        o: (3,) world-frame ray origin, outside the cylinder.
        d: (N, 3) world-frame ray directions; the ray parameter t is depth.

    Returns:
        ``(t (N,), normal (N, 3))`` as `box_hits`.
    """
    r, h = float(cyl[3]), float(cyl[4])
    q = o - cyl[:3]
    a = d[:, 0] ** 2 + d[:, 1] ** 2
    b = 2.0 * (q[0] * d[:, 0] + q[1] * d[:, 1])
    c = q[0] ** 2 + q[1] ** 2 - r * r
    disc = b * b - 4.0 * a * c
    with np.errstate(divide="ignore", invalid="ignore"):
        t_side = (-b - np.sqrt(disc)) / (2.0 * a)  # the nearer root: the camera is outside
    z_side = q[2] + t_side * d[:, 2]
    side = (disc >= 0.0) & (a > 0.0) & (t_side > 0.0) & (np.abs(z_side) <= h / 2.0)
    t = np.where(side, t_side, np.inf)
    normal_z = np.zeros(len(d))
    for zc in (h / 2.0, -h / 2.0):
        with np.errstate(divide="ignore", invalid="ignore"):
            t_cap = (zc - q[2]) / d[:, 2]
        xc, yc = q[0] + t_cap * d[:, 0], q[1] + t_cap * d[:, 1]
        cap = (t_cap > 0.0) & (xc * xc + yc * yc <= r * r) & (t_cap < t)
        t = np.where(cap, t_cap, t)
        normal_z = np.where(cap, math.copysign(1.0, zc), normal_z)
    n = np.zeros((len(d), 3))
    n[:, 2] = normal_z
    on_side = normal_z == 0.0
    with np.errstate(invalid="ignore"):
        n[on_side, 0] = (q[0] + t[on_side] * d[on_side, 0]) / r
        n[on_side, 1] = (q[1] + t[on_side] * d[on_side, 1]) / r
    return t, n


def cast_rays(
    scene: PrimitiveScene, o: np.ndarray, d: np.ndarray, unit: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The nearest hit of every ray over all primitives.

    Each primitive is tested only on the rays inside the cone of its bounding sphere that are
    not already stopped nearer; primitives go nearest first, so occluded ones cost little.

    Args:
        scene: The primitives.
        o: (3,) world-frame ray origin, outside every primitive.
        d: (N, 3) world-frame ray directions with unit depth.
        unit: (N, 3) the same directions, normalised.

    Returns:
        ``(t (N,), object_id (N,), normal (N, 3))``: depth (inf for none), id (-1 for none)
        and world-frame normal (NaN for none).
    """
    n = len(d)
    best = np.full(n, np.inf)
    best_range = np.full(n, np.inf)  # best t times the ray's length
    best_id = np.full(n, -1, dtype=np.int64)
    best_n = np.full((n, 3), np.nan)
    length = np.linalg.norm(d, axis=1)
    prims = [
        (b, i, box_hits, 0.5 * float(np.linalg.norm(b[3:6])))
        for b, i in zip(scene.boxes, scene.box_ids, strict=True)
    ] + [
        (c, i, cylinder_hits, math.hypot(c[3], c[4] / 2.0))
        for c, i in zip(scene.cylinders, scene.cylinder_ids, strict=True)
    ]
    near = [float(np.linalg.norm(p[0][:3] - o)) - p[3] for p in prims]
    for k in np.argsort(near, kind="stable"):
        prim, oid, hits, radius = prims[k]
        v = prim[:3] - o
        dist = float(np.linalg.norm(v))
        cand = best_range > dist - radius
        if dist > radius:
            cand &= unit @ v >= math.sqrt(dist * dist - radius * radius) - 1e-9
        idx = np.flatnonzero(cand)
        if len(idx) == 0:
            continue
        t, normal = hits(prim, o, d[idx])
        better = t < best[idx]
        sel = idx[better]
        best[sel] = t[better]
        best_range[sel] = t[better] * length[sel]
        best_id[sel] = oid
        best_n[sel] = normal[better]
    return best, best_id, best_n
