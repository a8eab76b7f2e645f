"""Change detection: did a pushed box move? The observed cloud against two predicted scans.

After a push the robot scans from the access cell and compares the observed cloud with
noise-free scans predicted from the believed map with the box moved one cell and with it in
place; the nearer hypothesis (`cloud_distance`, the symmetric mean nearest-neighbour distance)
is the observed outcome (`detect_push`). `VerifiedPush` records what the push did and what the
robot concluded.

Covered by tests/planning/manipulation/test_manipulation_loop.py.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from probaff._checks import as_bool_array, check_finite, check_shape
from probaff.errors import InputError
from probaff.grid import DIRECTION_OFFSETS
from probaff.sim.depth import DepthSensor
from probaff.sim.warehouse import WarehouseMap
from probaff.sim.warehouse_config import WarehouseSpec

__all__ = ["VerifiedPush", "cloud_distance", "detect_push"]


def cloud_distance(a: np.ndarray, b: np.ndarray) -> float:
    """Symmetric mean nearest-neighbour distance between two clouds.

    Args:
        a: (N, 3) points.
        b: (M, 3) points.

    Returns:
        The mean over both clouds of each point's distance to the nearest point of the other
        (m); ``inf`` if exactly one cloud is empty, 0 if both are.
    """
    if not len(a) and not len(b):
        return 0.0
    if not len(a) or not len(b):
        return math.inf
    d_ab, _ = cKDTree(b).query(a)
    d_ba, _ = cKDTree(a).query(b)
    return float((d_ab.sum() + d_ba.sum()) / (len(a) + len(b)))


def detect_push(
    spec: WarehouseSpec,
    believed: np.ndarray,
    cell: tuple[int, int],
    direction: int,
    observed: np.ndarray,
    position: np.ndarray,
) -> tuple[bool, float, float]:
    """Decide by change detection whether a pushed box moved.

    The two hypotheses are the believed map with the box in place and with it moved one cell
    (taken out of its cell and, if that cell lies inside the map, put in the next one). Each is
    scanned noise-free from `position` and compared with the observed cloud.

    Args:
        spec: The warehouse world (sensor model).
        believed: (rows, cols) bool, the boxes the robot believes in, before the push.
        cell: ``(row, col)`` of the pushed box.
        direction: Push direction (index into `DIRECTION_NAMES`).
        observed: (M, 3) world frame, the cloud scanned after the push.
        position: (2,) world frame xy of the sensor.

    Returns:
        ``(moved, d_moved, d_still)``: whether the "moved" prediction is nearer, and the two
        `cloud_distance` values (m).

    Raises:
        InputError: For a `cell` outside the map, an unknown `direction`, or a malformed
            cloud or position.
    """
    still = as_bool_array("believed", believed).copy()
    check_shape("believed", still, (None, None))
    try:
        rc = np.asarray(cell)
    except (TypeError, ValueError):  # a ragged sequence
        rc = np.zeros(0)
    if rc.shape != (2,) or not np.issubdtype(rc.dtype, np.integer):
        raise InputError(f"cell must be an integer (row, col) cell, got {cell!r}.")
    if not (0 <= rc[0] < still.shape[0] and 0 <= rc[1] < still.shape[1]):
        raise InputError(
            f"cell ({int(rc[0])}, {int(rc[1])}) lies outside the {still.shape[0]} x "
            f"{still.shape[1]} map."
        )
    cell = (int(rc[0]), int(rc[1]))
    if (
        isinstance(direction, bool)
        or not isinstance(direction, (int, np.integer))
        or not 0 <= direction < len(DIRECTION_OFFSETS)
    ):
        raise InputError(
            f"direction must be an index into DIRECTION_NAMES (0 to "
            f"{len(DIRECTION_OFFSETS) - 1}), got {direction!r}."
        )
    direction = int(direction)
    check_shape("observed", observed, (None, 3))
    check_finite("observed", observed)
    check_shape("position", position, (2,))
    check_finite("position", position)
    still[cell] = True
    moved = still.copy()
    moved[cell] = False
    dest = np.asarray(cell) + DIRECTION_OFFSETS[direction]
    if 0 <= dest[0] < still.shape[0] and 0 <= dest[1] < still.shape[1]:
        moved[dest[0], dest[1]] = True
    rng = np.random.default_rng(0)  # no noise is drawn; the generator is a formality
    scans = [
        DepthSensor(spec, WarehouseMap(occ, spec.cell_size)).scan(position, rng, exact=True).points
        for occ in (moved, still)
    ]
    d_moved, d_still = (cloud_distance(observed, s) for s in scans)
    return d_moved < d_still, d_moved, d_still


@dataclass(frozen=True)
class VerifiedPush:
    """What one push did, and what the robot concluded by change detection.

    (Not `probaff.sim.tabletop.PushOutcome`, the physics outcome of a tabletop push.)

    Attributes:
        real_box: A box truly stood in the pushed cell (the belief can be wrong).
        moved: The physics moved the box a cell (ground truth); False without a real box.
        observed: Change detection concluded that it moved.
        d_moved: Cloud distance to the "moved" prediction (m).
        d_still: Cloud distance to the "not moved" prediction (m).
        displacement: (2,) world displacement of the box in the physics (m).
    """

    real_box: bool
    moved: bool
    observed: bool
    d_moved: float
    d_still: float
    displacement: np.ndarray
