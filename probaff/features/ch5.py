"""Chapter 5 push features (n = 101): object, contact and context.

All quantities are in the pushing frame (origin at the hand's start pose, z_p along the push,
y_p to its left, x_p down), so they do not change when the whole scene is moved or turned
together with the push.

Columns:
    f_o (8): per object (o1, o2): centroid ``x_p, y_p, z_p`` of its cloud and the yaw of its
        principal axis from z_p, in (-pi/2, pi/2].
    f_c (13): the distance along z_p from the hand to the expected contact on o1, then for each
        finger (left: y_p > 0, right) the mean position (3) and mean normal (3) of the expected
        contact region. A finger's swept volume is 5 cm wide around the finger, from the hand
        to the end of the push, and from push height up the finger's length; the expected
        contact region is the part of o1's cloud in that volume within 1 cm of its nearest
        point. A finger whose volume misses o1 gets the position ``(0, y_finger, d_p)`` and a
        zero normal; if both miss, the distance is d_p.
    f_x (80): 20 bins of 2.5 cm along z_p from the hand; in each bin, for o1 and o2, the width
        (max - min of y_p) and the median y_p of the object's points; empty bins are 0.

Scenes with one object fill o2's columns with zeros; objects after o2 are not described.
"""

from __future__ import annotations

import numpy as np

from probaff.data.queries import PushInputs
from probaff.features._common import (
    FINGER_LENGTH,
    PushClouds,
    chunked,
    meta_float,
    principal_yaw,
)
from probaff.features.featureset import FeatureSet
from probaff.features.requirements import FEATURE_REQUIREMENTS

__all__ = ["CH5_BINS", "CH5_BIN_WIDTH", "REQUIRES", "chapter5_features"]

REQUIRES = FEATURE_REQUIREMENTS["ch5"]
"""What `chapter5_features` reads: the clouds, the push and the gripper's geometry in meta."""

CH5_BINS = 20
CH5_BIN_WIDTH = 0.025
_SWEEP_WIDTH = 0.05
_CONTACT_DEPTH = 0.01
_N_OBJ = 2


def _names() -> tuple[str, ...]:
    names = []
    for k in range(1, _N_OBJ + 1):
        names += [f"f_o.o{k}.x_p", f"f_o.o{k}.y_p", f"f_o.o{k}.z_p", f"f_o.o{k}.yaw"]
    names.append("f_c.distance")
    for side in ("left", "right"):
        names += [f"f_c.{side}.pos_{a}" for a in ("x", "y", "z")]
        names += [f"f_c.{side}.normal_{a}" for a in ("x", "y", "z")]
    for b in range(CH5_BINS):
        for k in range(1, _N_OBJ + 1):
            names += [f"f_x.bin{b}.o{k}.width", f"f_x.bin{b}.o{k}.median"]
    return tuple(names)


def _object(c: PushClouds) -> np.ndarray:
    n, K = c.points.shape[:2]
    out = np.zeros((n, _N_OBJ, 4))
    k = min(K, _N_OBJ)
    out[:, :k, :3] = c.points[:, :k].mean(axis=2)
    full = np.ones(c.points.shape[:3], dtype=bool)
    out[:, :k, 3] = principal_yaw(c.points[:, :k, :, 1], c.points[:, :k, :, 2], full[:, :k])
    return out.reshape(n, -1)


def _contact(c: PushClouds, opening: float, push_height: float) -> np.ndarray:
    n = c.points.shape[0]
    p, nrm = c.points[:, 0], c.normals[:, 0]  # o1: (n, P, 3)
    y, z = p[..., 1], p[..., 2]
    reach = (z >= 0) & (z <= c.distance[:, None]) & (c.height[:, 0] <= push_height + FINGER_LENGTH)
    out = np.zeros((n, 13))
    nearest = np.full(n, np.inf)
    for f, y_f in enumerate((0.5 * opening, -0.5 * opening)):
        hit = reach & (np.abs(y - y_f) <= 0.5 * _SWEEP_WIDTH)
        zmin = np.where(hit, z, np.inf).min(axis=1)
        region = hit & (z <= zmin[:, None] + _CONTACT_DEPTH)
        cnt = region.sum(1)
        safe = np.maximum(cnt, 1)[:, None]
        pos = (p * region[..., None]).sum(1) / safe
        normal = (nrm * region[..., None]).sum(1) / safe
        missed = cnt == 0
        pos[missed] = np.stack(
            [np.zeros(missed.sum()), np.full(missed.sum(), y_f), c.distance[missed]], -1
        )
        normal[missed] = 0.0
        out[:, 1 + 6 * f : 4 + 6 * f] = pos
        out[:, 4 + 6 * f : 7 + 6 * f] = normal
        nearest = np.minimum(nearest, zmin)
    out[:, 0] = np.where(np.isfinite(nearest), nearest, c.distance)
    return out


def _context(c: PushClouds) -> np.ndarray:
    n, K = c.points.shape[:2]
    out = np.zeros((n, CH5_BINS, _N_OBJ, 2))
    k = min(K, _N_OBJ)
    y, z = c.points[:, :k, :, 1], c.points[:, :k, :, 2]
    b = np.floor(z / CH5_BIN_WIDTH)
    for i in range(CH5_BINS):
        m = b == i
        yy = np.where(m, y, np.nan)
        has = m.any(-1)
        with np.errstate(all="ignore"):
            width = np.nanmax(np.where(m, y, -np.inf), -1) - np.nanmin(np.where(m, y, np.inf), -1)
            med = np.nanmedian(np.where(has[..., None], yy, 0.0), -1)
        out[:, i, :k, 0] = np.where(has, width, 0.0)
        out[:, i, :k, 1] = np.where(has, med, 0.0)
    return out.reshape(n, -1)


def chapter5_features(ds: PushInputs, chunk: int = 1024) -> FeatureSet:
    """Compute the chapter 5 features of every push.

    Args:
        ds: A push dataset, or candidate `PushQueries` (its clouds, push poses and gripper
            geometry are used).
        chunk: Pushes processed at once (bounds memory); a positive integer.

    Returns:
        A (N, 101) `FeatureSet` with groups ``f_o``, ``f_c``, ``f_x``.

    Raises:
        InputError: For an empty dataset, a `chunk` that is not a positive integer, or a
            dataset that lacks an array or ``meta`` entry of `REQUIRES` (naming it).
    """
    REQUIRES.check(ds)
    opening = meta_float(ds, "gripper_opening")
    height = meta_float(ds, "push_height")

    def fn(c: PushClouds) -> np.ndarray:
        return np.concatenate([_object(c), _contact(c, opening, height), _context(c)], axis=1)

    values = chunked(ds, 101, fn, chunk)
    groups = {"f_o": slice(0, 8), "f_c": slice(8, 21), "f_x": slice(21, 101)}
    return FeatureSet(values, groups, _names())
