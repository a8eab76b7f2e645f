"""Scenes of solid primitives for the depth camera: upright boxes and vertical cylinders.

A `PrimitiveScene` is what the ray caster (`probaff.sim.camera`) sees and what the office
scenes (`probaff.sim.office`) are built from: every primitive belongs to one object, named by
its integer id, and one object may be made of several primitives (a table's top and legs).

Frames: world frame, z up, metres. A box is given by its centre, its full extents along its own
axes and its yaw (rotation about world z, radians, counter-clockwise seen from above); a
cylinder by the centre of its axis, its radius and its full height, its axis along world z.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from probaff._checks import check_shape, real_float64
from probaff.errors import InputError
from probaff.sim.inputs import float_rows

__all__ = ["PrimitiveScene"]


def _numbers(name: str, value: object, columns: int) -> np.ndarray:
    """`value` as a float64 array, or an `InputError` asking for an (N, `columns`) array."""
    arr = real_float64(value)
    if arr is None:
        raise InputError(f"{name} must be an (N, {columns}) array of numbers, got {value!r}.")
    return arr


def _array(name: str, value: object, columns: int) -> np.ndarray:
    return float_rows(name, _numbers(name, value, columns), columns)


def _ids(name: str, value: object, n: int) -> np.ndarray:
    arr = np.asarray(value)
    if arr.size == 0:
        arr = arr.reshape(0).astype(np.int64)
    if arr.shape != (n,) or (arr.size and not np.issubdtype(arr.dtype, np.integer)):
        raise InputError(f"{name} must be ({n},) integer object ids, got shape {arr.shape}.")
    if arr.size and arr.min() < 0:
        raise InputError(f"{name} must be >= 0 (object ids), got {int(arr.min())}.")
    return arr.astype(np.int64)


@dataclass(frozen=True)
class PrimitiveScene:
    """Upright boxes and vertical cylinders, each tagged with its object's id.

    Attributes:
        boxes: (B, 7) ``(cx, cy, cz, sx, sy, sz, yaw)``: centre (m), full extents along the
            box's own x, y, z (m, > 0) and yaw about world z (rad).
        box_ids: (B,) object id of each box (>= 0).
        cylinders: (C, 5) ``(cx, cy, cz, radius, height)``: the axis centre (m), the radius and
            the full height (m, > 0); the axis is world z.
        cylinder_ids: (C,) object id of each cylinder (>= 0).

    Raises:
        InputError: For wrong shapes, non-finite values, extents that are not positive or
            ids that are not non-negative integers, naming the array.
    """

    boxes: np.ndarray = field(default_factory=lambda: np.zeros((0, 7)))
    box_ids: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    cylinders: np.ndarray = field(default_factory=lambda: np.zeros((0, 5)))
    cylinder_ids: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))

    def __post_init__(self) -> None:
        boxes = _array("boxes", self.boxes, 7)
        cylinders = _array("cylinders", self.cylinders, 5)
        if np.any(boxes[:, 3:6] <= 0):
            raise InputError("boxes must have positive extents (columns 3-5: sx, sy, sz).")
        if np.any(cylinders[:, 3:5] <= 0):
            raise InputError("cylinders must have a positive radius and height (columns 3, 4).")
        object.__setattr__(self, "boxes", boxes)
        object.__setattr__(self, "cylinders", cylinders)
        object.__setattr__(self, "box_ids", _ids("box_ids", self.box_ids, len(boxes)))
        object.__setattr__(
            self, "cylinder_ids", _ids("cylinder_ids", self.cylinder_ids, len(cylinders))
        )
        if len(boxes) + len(cylinders) == 0:
            raise InputError("the scene holds no primitives; give at least one box or cylinder.")

    @property
    def object_ids(self) -> np.ndarray:
        """(K,) the sorted distinct object ids of the scene."""
        return np.unique(np.concatenate([self.box_ids, self.cylinder_ids]))

    def contains(self, points: np.ndarray) -> np.ndarray:
        """Whether each of the points `(N, 3)` (world) lies strictly inside some primitive.

        Returns:
            (N,) bool.
        """
        p = _numbers("points", points, 3)
        check_shape("points", p, (None, 3))
        inside = np.zeros(len(p), dtype=bool)
        for cx, cy, cz, sx, sy, sz, yaw in self.boxes:
            c, s = np.cos(yaw), np.sin(yaw)
            d = p - (cx, cy, cz)
            u, v = c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1]
            inside |= (np.abs(u) < sx / 2) & (np.abs(v) < sy / 2) & (np.abs(d[:, 2]) < sz / 2)
        for cx, cy, cz, r, h in self.cylinders:
            d = p - (cx, cy, cz)
            inside |= (d[:, 0] ** 2 + d[:, 1] ** 2 < r * r) & (np.abs(d[:, 2]) < h / 2)
        return inside
