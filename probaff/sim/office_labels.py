"""Ground-truth affordance labels of an office scene's objects, one label vector per object.

Labels, in the order of `LABELS`, by the thesis's manual labelling criteria (section 2.3.3):

- The floor and the walls carry no label (all false).
- All segments of an object share its labels: labels are per object.
- Pushable in a direction d unless blocked: another object (a wall included, the floor and the
  object's own load excluded) lies on the d side, its footprint's gap along d is below
  ``labels.push_clearance`` (0.15 m, our choice: about one gripper span, the room the hand needs
  beside an object and a short push step) and its footprint's extent across d overlaps this one's
  by more than 0 m, and their height ranges overlap. Footprints are the object's parts projected
  on the floor; gap and overlap are measured on their projections along d and across it.
- An object standing on another object (a table top or a box) is pushable every way: the
  thesis's "physically feasible primitive", even though it may fall off. A table, chair or box
  with something on it is still pushable unless blocked.
- Liftable when nothing stands on it, its mass is at most ``labels.max_lift_mass`` (1.8 kg, the
  PR2's payload, thesis section 2.6) and its largest horizontal extent at most
  ``labels.max_lift_size`` (0.6 m, our choice: what two arms can hold). Tables (15-30 kg) are not
  liftable; chairs (1.0-1.8 kg) and boxes are, unless something is on them or they are too big or
  heavy.
- Graspable when some part is thinner than ``labels.gripper_span`` (0.15 m, the thesis's PR2
  gripper) across which the fingers close horizontally: a box whose smaller horizontal extent is
  below the span, a chair's back or legs, a table's legs or a thin pedestal. Our choice: a table
  top's edge (2-4 cm thick) does not count, since the fingers would have to close vertically
  round a plate whose far side they cannot reach; a four-legged table is graspable by its legs,
  a pedestal table only if the pedestal's diameter is below the span.

Push directions are in the robot frame: forward = robot +x, backward = -x, left = +y,
right = -y.

Covered by tests/sim/test_office.py.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from probaff._checks import check_finite, check_shape
from probaff.affordance_labels import LABELS
from probaff.sim.office_config import OfficeLabelRules
from probaff.sim.office_objects import (
    OfficeObject,
    check_objects,
    floats,
    footprint_corners,
)

__all__ = ["office_labels"]

# Push directions in the robot frame, in the order of LABELS[:4].
_ROBOT_DIRECTIONS = np.array([[1.0, 0.0], [-1.0, 0.0], [0.0, 1.0], [0.0, -1.0]])


def _projection(obj: OfficeObject, d: np.ndarray) -> tuple[float, float]:
    """Interval (m) of the object's footprint projected on the unit xy direction `d` (2,)."""
    centre = obj.cylinders[:, :2] @ d
    r = obj.cylinders[:, 3]
    vals = np.concatenate([footprint_corners(obj.boxes) @ d, centre - r, centre + r])
    return float(vals.min()), float(vals.max())


def _blocks(
    k: int, m: int, axis: int, sign: int, iv: np.ndarray, z: np.ndarray, clearance: float
) -> bool:
    """Whether object `m` blocks pushing object `k` along ``sign`` times robot axis `axis`.

    Args:
        k: Row of the pushed object.
        m: Row of the other object.
        axis: 0 for the robot's x (forward/backward), 1 for its y (left/right).
        sign: +1 (forward, left) or -1 (backward, right).
        iv: (K, 2, 2) footprint intervals ``(lo, hi)`` of each object projected on the robot's
            x and y axes (m, world xy projected on the robot's axes).
        z: (K, 2) height range ``(lo, hi)`` of each object (m).
        clearance: The push clearance (m).
    """
    if min(z[k, 1], z[m, 1]) - max(z[k, 0], z[m, 0]) <= 0:
        return False
    lo, hi = sorted(sign * iv[k, axis])
    olo, ohi = sorted(sign * iv[m, axis])
    if olo + ohi <= lo + hi or olo - hi >= clearance:  # not on that side, or far enough
        return False
    (plo, phi), (qlo, qhi) = iv[k, 1 - axis], iv[m, 1 - axis]
    return bool(min(phi, qhi) - max(plo, qlo) > 0)


def office_labels(
    objects: Sequence[OfficeObject], rules: OfficeLabelRules, robot_yaw: float = 0.0
) -> np.ndarray:
    """Ground-truth labels of every object by the rules of the module docstring.

    Args:
        objects: The K objects of a scene (ids unique, supports among them or -1).
        rules: The thresholds.
        robot_yaw: The robot's yaw in the world (rad); push directions are in its frame.

    Returns:
        (K, 6) bool, row k for ``objects[k]``, columns in the order of `LABELS`.

    Raises:
        InputError: For objects that do not form a consistent scene (see
            `assemble_office_scene`) or a non-finite yaw.
    """
    check_objects(objects)
    yaw = floats("robot_yaw", robot_yaw)
    check_shape("robot_yaw", yaw, ())
    check_finite("robot_yaw", yaw)
    c, s = math.cos(float(yaw)), math.sin(float(yaw))
    world_dirs = _ROBOT_DIRECTIONS @ np.array([[c, s], [-s, c]])
    children: dict[int, list[int]] = {o.id: [] for o in objects}
    for o in objects:
        if o.support >= 0:
            children[o.support].append(o.id)
    iv = np.array([[_projection(o, a) for a in world_dirs[[0, 2]]] for o in objects])
    z = np.array([o.z_range for o in objects])
    labels = np.zeros((len(objects), len(LABELS)), dtype=bool)
    for k, o in enumerate(objects):
        if o.kind in ("floor", "wall"):
            continue
        if o.support >= 0:
            labels[k, :4] = True
        else:
            load = _descendants(o.id, children)
            others = [
                m
                for m, b in enumerate(objects)
                if b.kind != "floor" and b.id != o.id and b.id not in load
            ]
            for j in range(4):
                axis, sign = j // 2, 1 - 2 * (j % 2)
                labels[k, j] = not any(
                    _blocks(k, m, axis, sign, iv, z, rules.push_clearance) for m in others
                )
        lo, hi = o.bounds
        size = float(max(hi[0] - lo[0], hi[1] - lo[1]))
        labels[k, 4] = (
            not children[o.id] and o.mass <= rules.max_lift_mass and size <= rules.max_lift_size
        )
        labels[k, 5] = o.grasp_width < rules.gripper_span
    return labels


def _descendants(root: int, children: dict[int, list[int]]) -> set[int]:
    out: set[int] = set()
    todo = list(children[root])
    while todo:
        i = todo.pop()
        if i not in out:
            out.add(i)
            todo.extend(children[i])
    return out
