"""The objects of an office scene and the checks that they form a physically consistent scene.

An object has an integer id, a kind (`KINDS`), a name, its solid parts (upright boxes with a yaw
and vertical cylinders) and the id of the object it stands on. World frame, z up from the floor
(the floor's top is z = 0), metres, kilograms.

Covered by tests/sim/test_office.py.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from probaff._checks import check_count, check_positive
from probaff.errors import InputError
from probaff.sim.geometry import convex_penetration, rect_disc_penetration
from probaff.sim.inputs import float_rows, floats

__all__ = ["KINDS", "OfficeObject", "check_objects", "footprint_corners", "xy_points"]

KINDS = ("floor", "wall", "table", "chair", "box")
"""The kinds of office objects; the floor and the walls are the room's fixed structure."""
_STRUCTURE = ("floor", "wall")
_OVERLAP_TOL = 1e-6  # m; solids may interpenetrate this much (faces in contact)
_REST_TOL = 1e-3  # m; an object rests on a surface whose height is this close to its bottom


def _parts(name: str, value: object, columns: int) -> np.ndarray:
    return float_rows(name, floats(name, value), columns)


@dataclass(frozen=True, eq=False)
class OfficeObject:
    """One object of an office scene and its solid parts.

    Attributes:
        id: Object id (>= 0), unique in its scene; the ids of its primitives.
        kind: One of `KINDS`.
        name: A readable name, e.g. ``"table_0"``.
        support: Id of the object it stands on, or -1 for the floor (and for the floor and
            walls themselves).
        boxes: (P, 7) world frame ``(cx, cy, cz, sx, sy, sz, yaw)``, its box parts (m, rad).
        cylinders: (Q, 5) world frame ``(cx, cy, cz, radius, height)``, its cylinder parts.
        mass: Mass (kg, >= 0; 0 for the fixed floor and walls).

    Raises:
        InputError: For an unknown kind, a bad id or support, malformed parts or no parts.
    """

    id: int
    kind: str
    name: str
    support: int = -1
    boxes: np.ndarray = field(default_factory=lambda: np.zeros((0, 7)))
    cylinders: np.ndarray = field(default_factory=lambda: np.zeros((0, 5)))
    mass: float = 0.0

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise InputError(f"kind: unknown object kind {self.kind!r}; use one of {list(KINDS)}.")
        object.__setattr__(self, "id", check_count("id", self.id, minimum=0))
        object.__setattr__(self, "support", check_count("support", self.support, minimum=-1))
        if self.support == self.id:
            raise InputError(f"support: object {self.id} cannot stand on itself.")
        boxes = _parts("boxes", self.boxes, 7)
        cylinders = _parts("cylinders", self.cylinders, 5)
        if len(boxes) + len(cylinders) == 0:
            raise InputError(
                f"object {self.id} ({self.name}) has no parts; give a box or cylinder."
            )
        if np.any(boxes[:, 3:6] <= 0) or np.any(cylinders[:, 3:5] <= 0):
            raise InputError(f"object {self.id} ({self.name}): part extents must be > 0.")
        check_positive("mass", self.mass, allow_zero=True)
        object.__setattr__(self, "boxes", boxes)
        object.__setattr__(self, "cylinders", cylinders)
        object.__setattr__(self, "mass", float(self.mass))

    @property
    def bounds(self) -> np.ndarray:
        """(2, 3) world frame: the lower and upper corners of its axis-aligned bounding box."""
        xy = xy_points(self)
        z0, z1 = self.z_range
        return np.array([[*xy.min(axis=0), z0], [*xy.max(axis=0), z1]])

    @property
    def z_range(self) -> tuple[float, float]:
        """Lowest and highest z of its parts (m, world)."""
        zs = np.concatenate(
            [
                self.boxes[:, 2] - self.boxes[:, 5] / 2,
                self.boxes[:, 2] + self.boxes[:, 5] / 2,
                self.cylinders[:, 2] - self.cylinders[:, 4] / 2,
                self.cylinders[:, 2] + self.cylinders[:, 4] / 2,
            ]
        )
        return float(zs.min()), float(zs.max())

    @property
    def grasp_width(self) -> float:
        """Thinnest horizontal width of its parts (m): min(sx, sy) of a box, 2 r of a cylinder."""
        widths = np.concatenate([self.boxes[:, 3:5].min(axis=1), 2 * self.cylinders[:, 3]])
        return float(widths.min())


def footprint_corners(boxes: np.ndarray) -> np.ndarray:
    """(4 P, 2) world xy: the footprint corners of the boxes `boxes` (P, 7)."""
    signs = np.array([[1, 1], [1, -1], [-1, 1], [-1, -1]], dtype=np.float64)
    c, s = np.cos(boxes[:, 6:7]), np.sin(boxes[:, 6:7])
    u = signs[None, :, 0] * boxes[:, 3:4] / 2
    v = signs[None, :, 1] * boxes[:, 4:5] / 2
    x = boxes[:, 0:1] + c * u - s * v
    y = boxes[:, 1:2] + s * u + c * v
    return np.stack([x, y], axis=-1).reshape(-1, 2)


def xy_points(obj: OfficeObject) -> np.ndarray:
    """(M, 2) world xy: its box corners and the 4 axis-extreme points of each cylinder."""
    axes = np.array([[1, 0], [-1, 0], [0, 1], [0, -1]], dtype=np.float64)
    cyl = obj.cylinders
    round_pts = (cyl[:, None, :2] + cyl[:, None, 3:4] * axes[None]).reshape(-1, 2)
    return np.concatenate([footprint_corners(obj.boxes), round_pts])


def check_objects(objects: Sequence[OfficeObject]) -> None:
    """Raise `InputError` unless `objects` form a physically consistent scene.

    Ids are unique; every support is in the scene, is neither the floor nor a wall (objects on
    the floor take -1) and the supports form no cycle; the floor and walls stand on nothing;
    no two objects' solids interpenetrate; an object on the floor has its lowest point on the
    floor's top (z = 0) and its footprint on a floor object of the scene, if there is one;
    an object on another rests on one of that object's top faces.
    """
    if isinstance(objects, (str, bytes)) or not isinstance(objects, Sequence):
        raise InputError(f"objects must be a list of OfficeObject, got {type(objects).__name__}.")
    if len(objects) == 0:
        raise InputError("objects is empty; give at least one OfficeObject.")
    for i, o in enumerate(objects):
        if not isinstance(o, OfficeObject):
            raise InputError(f"objects[{i}] must be an OfficeObject, got {type(o).__name__}.")
    ids = [o.id for o in objects]
    if len(set(ids)) != len(ids):
        raise InputError("objects: object ids must be unique.")
    by_id = {o.id: o for o in objects}
    for o in objects:
        if o.support < 0:
            continue
        if o.support not in by_id:
            raise InputError(
                f"objects: {o.name} stands on object {o.support}, which is not in the scene."
            )
        base = by_id[o.support]
        if o.kind in _STRUCTURE:
            raise InputError(
                f"objects: {o.name} (id {o.id}) is a {o.kind} and stands on nothing; give it "
                "support -1."
            )
        if base.kind in _STRUCTURE:
            raise InputError(
                f"objects: {o.name} (id {o.id}) has support {base.id}, the {base.kind} "
                f"{base.name}; an object standing on the floor takes support -1, and nothing "
                "stands on a wall."
            )
    _check_support_cycles(objects, by_id)
    _check_overlaps(objects)
    _check_resting(objects, by_id)


def _check_support_cycles(objects: Sequence[OfficeObject], by_id: dict[int, OfficeObject]) -> None:
    """Raise `InputError` if following supports from some object comes back to it."""
    done: set[int] = set()
    for o in objects:
        chain: list[int] = []
        oid = o.id
        while oid >= 0 and oid not in done:
            if oid in chain:
                loop = [*chain[chain.index(oid) :], oid]
                names = " on ".join(f"{by_id[i].name} (id {i})" for i in loop)
                raise InputError(
                    f"objects: the supports form a cycle, {names}; every chain of supports "
                    "must end on the floor (support -1)."
                )
            chain.append(oid)
            oid = by_id[oid].support
        done.update(chain)


def _solids(objects: Sequence[OfficeObject]) -> tuple[np.ndarray, ...]:
    """Every part of every object: owner row, kind (0 box, 1 cylinder), row, bounds (P, 6)."""
    owner, kind, row, lo, hi = [], [], [], [], []
    for k, o in enumerate(objects):
        for r, b in enumerate(o.boxes):
            xy = footprint_corners(b[None])
            owner.append(k)
            kind.append(0)
            row.append(r)
            lo.append([*xy.min(axis=0), b[2] - b[5] / 2])
            hi.append([*xy.max(axis=0), b[2] + b[5] / 2])
        for r, c in enumerate(o.cylinders):
            owner.append(k)
            kind.append(1)
            row.append(r)
            lo.append([c[0] - c[3], c[1] - c[3], c[2] - c[4] / 2])
            hi.append([c[0] + c[3], c[1] + c[3], c[2] + c[4] / 2])
    return (
        np.array(owner, dtype=np.int64),
        np.array(kind, dtype=np.int64),
        np.array(row, dtype=np.int64),
        np.array(lo, dtype=np.float64).reshape(-1, 3),
        np.array(hi, dtype=np.float64).reshape(-1, 3),
    )


def _footprint_depth(a: OfficeObject, ka: int, ra: int, b: OfficeObject, kb: int, rb: int) -> float:
    """Depth (m) by which the footprints of part `ra` of `a` and part `rb` of `b` overlap."""
    if ka == 0 and kb == 0:
        return convex_penetration(
            footprint_corners(a.boxes[ra : ra + 1])[[0, 1, 3, 2]],
            footprint_corners(b.boxes[rb : rb + 1])[[0, 1, 3, 2]],
        )
    if ka == 1 and kb == 1:
        p, q = a.cylinders[ra], b.cylinders[rb]
        return float(p[3] + q[3] - math.hypot(p[0] - q[0], p[1] - q[1]))
    box, cyl = (a.boxes[ra], b.cylinders[rb]) if ka == 0 else (b.boxes[rb], a.cylinders[ra])
    return rect_disc_penetration(box[:2], (box[3], box[4]), box[6], cyl[:2], cyl[3])


def _check_overlaps(objects: Sequence[OfficeObject]) -> None:
    """Raise `InputError` naming the first two objects whose solids interpenetrate.

    Parts are upright prisms (boxes with a yaw, vertical cylinders), so two parts
    interpenetrate exactly when their height ranges and their footprints both overlap; the
    depth is the smaller of the two overlaps. Bounding boxes pick the candidate pairs first.
    """
    owner, kind, row, lo, hi = _solids(objects)
    i, j = np.triu_indices(len(owner), k=1)
    cand = owner[i] != owner[j]
    i, j = i[cand], j[cand]
    reach = np.minimum(hi[i], hi[j]) - np.maximum(lo[i], lo[j])  # (M, 3) overlap per axis
    cand = np.all(reach > _OVERLAP_TOL, axis=1)
    for a, b, dz in zip(i[cand], j[cand], reach[cand, 2], strict=True):
        oa, ob = objects[owner[a]], objects[owner[b]]
        depth = min(float(dz), _footprint_depth(oa, kind[a], row[a], ob, kind[b], row[b]))
        if depth > _OVERLAP_TOL:
            raise InputError(
                f"objects: {oa.name} (id {oa.id}) and {ob.name} (id {ob.id}) overlap by "
                f"{1000 * depth:.1f} mm; move them apart, or stand one on the other (its "
                "bottom on the other's top, its support set to the other's id)."
            )


def _on_part(x: float, y: float, z: float, obj: OfficeObject) -> bool:
    """Whether the point (x, y, z) lies on a top face of a part of `obj` (within tolerances)."""
    for b in obj.boxes:
        c, s = math.cos(b[6]), math.sin(b[6])
        u, v = c * (x - b[0]) + s * (y - b[1]), -s * (x - b[0]) + c * (y - b[1])
        top = b[2] + b[5] / 2
        if abs(z - top) <= _REST_TOL and abs(u) <= b[3] / 2 and abs(v) <= b[4] / 2:
            return True
    for cy in obj.cylinders:
        top = cy[2] + cy[4] / 2
        if abs(z - top) <= _REST_TOL and math.hypot(x - cy[0], y - cy[1]) <= cy[3]:
            return True
    return False


def _check_resting(objects: Sequence[OfficeObject], by_id: dict[int, OfficeObject]) -> None:
    """Raise `InputError` for an object that floats, sinks, or stands off its support."""
    floors = [o.bounds for o in objects if o.kind == "floor"]
    for o in objects:
        if o.kind in _STRUCTURE:
            continue
        (x0, y0, z0), (x1, y1, _) = o.bounds
        if o.support < 0:
            if abs(z0) > _REST_TOL:
                raise InputError(
                    f"objects: {o.name} (id {o.id}) has support -1 (the floor) but its lowest "
                    f"point is at z={z0:.3f} m; stand it on the floor (z = 0), or give the id "
                    "of the object it stands on as its support."
                )
            inside = [
                f
                for f in floors
                if x0 >= f[0, 0] - _OVERLAP_TOL
                and x1 <= f[1, 0] + _OVERLAP_TOL
                and y0 >= f[0, 1] - _OVERLAP_TOL
                and y1 <= f[1, 1] + _OVERLAP_TOL
            ]
            if floors and not inside:
                f = floors[0]
                raise InputError(
                    f"objects: {o.name} (id {o.id}) reaches off the floor: its footprint spans "
                    f"x [{x0:.3f}, {x1:.3f}], y [{y0:.3f}, {y1:.3f}] m, the floor x "
                    f"[{f[0, 0]:.3f}, {f[1, 0]:.3f}], y [{f[0, 1]:.3f}, {f[1, 1]:.3f}] m; move "
                    "it onto the floor."
                )
            continue
        base = by_id[o.support]
        cx, cy = (x0 + x1) / 2, (y0 + y1) / 2
        if not _on_part(cx, cy, z0, base):
            raise InputError(
                f"objects: {o.name} (id {o.id}) stands on {base.name} (id {base.id}), but its "
                f"bottom (centre ({cx:.3f}, {cy:.3f}), z={z0:.3f} m) is not on a top face of "
                f"{base.name}; place it on that object's top, or correct its support."
            )
