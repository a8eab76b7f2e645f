"""Context descriptors of point-cloud segments: size, support, load and free space around.

The 25 features of `segment_features` describe a segment on its own, but the office's labels
are set by what lies around the object (`probaff.sim.office_labels`): a push is blocked by a
neighbour within the push clearance, a load on top makes an object not liftable, and an
object standing on another is pushable every way. `context_features` gives each segment of a
view the columns of `CONTEXT_NAMES`, read off the view's points (all of them, in a segment or
not):

* 0 ``log_points``: ``log10`` of the segment's point count;
* 1-2 ``z_min``, ``z_max``: the segment's height range (m);
* 3 ``support_z``: the top of what lies beneath the segment: the highest point of the view
  (floor included, the segment's own points excluded) inside the segment's xy bounding box
  and below ``z_min + support_tolerance``; 0 (the floor) when none;
* 4 ``height_above_support``: ``z_min - support_z`` (m);
* 5 ``load``: ``log10(1 + n)``, n the points of the view (the segment's own excluded) inside
  the segment's xy bounding box and in ``(z_max - support_tolerance, z_max + load_height]``:
  what stands on the segment;
* 6-9 ``gap_front``, ``gap_back``, ``gap_left``, ``gap_right``: the free space beside the
  segment along robot +x, -x, +y, -y: the distance from the segment's bounding box to the
  nearest point of the view (the segment's own and the floor's excluded) that lies on that
  side, within the box's extent across that direction and at a height in ``[floor_height,
  z_max]``; ``max_gap`` when none (nothing seen within it);
* 10-18 the same read off the segment's contact group, an object hypothesis: region growing
  cuts an object into many segments (a table into its top and legs, a chair into seat, back
  and legs), and the labels are the object's, so each segment also gets the descriptors of the
  connected set of points above the floor that holds it. The view's points at least
  ``floor_height`` high (in a segment or not: the unassigned points along creases join an
  object's segments) are binned into cubes of ``link_distance``; cubes that share a face, an
  edge or a corner are connected, and a segment's group is the component holding most of its
  points (a floor segment, with no point that high, is its own group). Columns:
  ``group_log_points``, ``group_span_x``, ``group_span_y``, ``group_span_z``,
  ``group_z_max`` and ``group_gap_front`` .. ``group_gap_right`` (as columns 6-9 with the
  group's points as its own);
* 19-22 ``group_floor_front`` .. ``group_floor_right``: ``log10(1 + n)``, n the floor points
  (below ``floor_height``) seen in the strip beside the group's bounding box, from its edge
  out to ``clearance``, within its extent across that direction. The camera looks at an
  object's near side, so the space behind it is often hidden: seen floor there says the side
  is free, where a large gap alone may only mean nothing was seen.

Options (`ContextOptions`, our choices): ``floor_height = 0.05`` m (points below are the
floor: above the camera's depth noise at 3 m, below the lowest office part that is not the
floor), ``support_tolerance = 0.03`` m (the band above and below a contact), ``load_height =
0.5`` m (the tallest office object on a table or a box), ``max_gap = 1.0`` m (well beyond the
0.15 m push clearance, so a free side reads as far), ``link_distance = 0.04`` m (bridges the
band of about 3 pixels that region growing leaves along a crease at 2 m, below the 0.15 m
clearance between objects that the labels treat as apart), ``clearance = 0.15`` m (the
office's push clearance, `probaff.sim.office_labels`).

Frames and units: points in the robot frame (x forward, y left, z up, floor at z = 0),
metres.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike
from scipy import ndimage

from probaff._checks import as_float_array, check_count, check_finite, check_number, check_shape
from probaff.errors import InputError

__all__ = ["CONTEXT_NAMES", "ContextOptions", "context_features"]

CONTEXT_NAMES: tuple[str, ...] = (
    "log_points",
    "z_min",
    "z_max",
    "support_z",
    "height_above_support",
    "load",
    "gap_front",
    "gap_back",
    "gap_left",
    "gap_right",
    "group_log_points",
    "group_span_x",
    "group_span_y",
    "group_span_z",
    "group_z_max",
    "group_gap_front",
    "group_gap_back",
    "group_gap_left",
    "group_gap_right",
    "group_floor_front",
    "group_floor_back",
    "group_floor_left",
    "group_floor_right",
)
"""Column names of `context_features`."""


@dataclass(frozen=True)
class ContextOptions:
    """Thresholds of `context_features` (see the module docstring for their sources).

    Attributes:
        floor_height: Points below this height are the floor (m, > 0).
        support_tolerance: Height band of a contact above or below a segment (m, > 0).
        load_height: How far above a segment a load is looked for (m, > 0).
        max_gap: The gap reported when nothing lies on a side (m, > 0).
        link_distance: Edge of the cubes whose neighbours connect a contact group (m, > 0).
        clearance: Depth of the strips beside a group where seen floor is counted (m, > 0).

    Raises:
        InputError: Naming a field that is not a finite number > 0.
    """

    floor_height: float = 0.05
    support_tolerance: float = 0.03
    load_height: float = 0.5
    max_gap: float = 1.0
    link_distance: float = 0.04
    clearance: float = 0.15

    def __post_init__(self) -> None:
        for name in (
            "floor_height",
            "support_tolerance",
            "load_height",
            "max_gap",
            "link_distance",
            "clearance",
        ):
            value = check_number(name, getattr(self, name), bound="> 0", unit="m")
            object.__setattr__(self, name, value)


def _inputs(points: ArrayLike, rows: ArrayLike, n_segments: int) -> tuple[np.ndarray, np.ndarray]:
    """Checked (N, 3) float points and (N,) int64 rows."""
    pts = as_float_array("points", points)
    check_shape("points", pts, (None, 3))
    check_finite("points", pts)
    check_shape("rows", rows, (pts.shape[0],))
    lab = np.asarray(rows)
    if lab.dtype.kind not in "iu":
        raise InputError(
            f"rows must be integer segment rows (-1 for no segment), got dtype {lab.dtype}."
        )
    lab = lab.astype(np.int64)
    if lab.size and (lab.min() < -1 or lab.max() >= n_segments):
        raise InputError(
            f"rows must lie in [-1, n_segments - 1] = [-1, {n_segments - 1}], got values in "
            f"[{lab.min()}, {lab.max()}]."
        )
    counts = np.bincount(lab[lab >= 0], minlength=n_segments)
    if n_segments and counts.min() == 0:
        empty = int(np.argmin(counts))
        raise InputError(f"segment row {empty} has no points; every row needs at least one.")
    return pts, lab


def context_features(
    points: ArrayLike,
    rows: ArrayLike,
    n_segments: int,
    options: ContextOptions | None = None,
) -> np.ndarray:
    """The context descriptors `CONTEXT_NAMES` of each segment of one view.

    Args:
        points: (N, 3) the view's returned points (robot frame, m), finite.
        rows: (N,) int each point's segment row in [0, n_segments), or -1 for none.
        n_segments: S, the number of segments (each row must hold a point).
        options: The thresholds; `ContextOptions()` when None.

    Returns:
        (S, 23) float64, columns `CONTEXT_NAMES`.

    Raises:
        InputError: For points not (N, 3) or not finite, rows of the wrong length, type or
            range, a segment row without points, or options that are not `ContextOptions`.
    """
    s = check_count("n_segments", n_segments, minimum=0)
    opt = ContextOptions() if options is None else options
    if not isinstance(opt, ContextOptions):
        raise InputError(f"options must be a ContextOptions, got {type(opt).__name__}.")
    pts, lab = _inputs(points, rows, s)
    out = np.empty((s, len(CONTEXT_NAMES)))
    if s == 0:
        return out
    x, y, z = pts[:, 0], pts[:, 1], pts[:, 2]
    solid = z >= opt.floor_height
    group = _contact_groups(pts, solid, opt.link_distance)
    order = np.argsort(lab, kind="stable")
    starts = np.searchsorted(lab[order], np.arange(s + 1))
    tol = opt.support_tolerance
    cache: dict[int, np.ndarray] = {}
    for r in range(s):
        members = order[starts[r] : starts[r + 1]]
        own = pts[members]
        lo, hi = own.min(axis=0), own.max(axis=0)
        other = lab != r
        in_x = (x >= lo[0]) & (x <= hi[0])
        in_y = (y >= lo[1]) & (y <= hi[1])
        column = other & in_x & in_y
        below = column & (z < lo[2] + tol)
        support = max(float(z[below].max()), 0.0) if below.any() else 0.0
        load = column & (z > hi[2] - tol) & (z <= hi[2] + opt.load_height)
        ids = group[members]
        ids = ids[ids >= 0]
        if ids.size:
            g = int(np.bincount(ids).argmax())
            if g not in cache:
                cache[g] = _group_row(pts, group == g, solid, opt)
            whole = cache[g]
        else:
            whole = _group_row(pts, lab == r, solid, opt)
        out[r, :10] = (
            np.log10(len(own)),
            lo[2],
            hi[2],
            support,
            lo[2] - support,
            np.log10(1.0 + np.count_nonzero(load)),
            *_gaps(pts, other & solid, lo, hi, opt.max_gap),
        )
        out[r, 10:] = whole
    return out


def _contact_groups(pts: np.ndarray, solid: np.ndarray, cube: float) -> np.ndarray:
    """(N,) int64 contact group of each point at least floor high, -1 for the others."""
    group = np.full(len(pts), -1, dtype=np.int64)
    if not solid.any():
        return group
    cells = np.floor(pts[solid] / cube).astype(np.int64)
    cells -= cells.min(axis=0)
    grid = np.zeros(tuple(cells.max(axis=0) + 1), dtype=bool)
    grid[tuple(cells.T)] = True
    components, _ = ndimage.label(grid, structure=np.ones((3, 3, 3), dtype=bool))
    group[solid] = components[tuple(cells.T)] - 1
    return group


def _box_sides(
    x: np.ndarray, y: np.ndarray, lo: np.ndarray, hi: np.ndarray
) -> tuple[tuple[np.ndarray, np.ndarray, float], ...]:
    """The four sides +x, -x, +y, -y of the box ``[lo, hi]`` seen from points at `x`, `y` (N,).

    Each side is ``(ahead, across, edge)``: each point's coordinate along the side's outward
    direction, whether it lies within the box's extent across that direction, and the
    coordinate of the box's face along it.
    """
    in_x = (x >= lo[0]) & (x <= hi[0])
    in_y = (y >= lo[1]) & (y <= hi[1])
    return ((x, in_y, hi[0]), (-x, in_y, -lo[0]), (y, in_x, hi[1]), (-y, in_x, -lo[1]))


def _gaps(
    pts: np.ndarray, others: np.ndarray, lo: np.ndarray, hi: np.ndarray, max_gap: float
) -> list[float]:
    """Free space (m) beside the box ``[lo, hi]`` along +x, -x, +y, -y among `others` (N,).

    Only the points of `others` at most ``hi[2]`` high and within the box's extent across a
    direction count; `max_gap` when none lies on a side.
    """
    level = others & (pts[:, 2] <= hi[2])
    gaps = []
    for side, across, edge in _box_sides(pts[:, 0], pts[:, 1], lo, hi):
        beyond = level & across & (side > edge)
        gap = float(side[beyond].min() - edge) if beyond.any() else max_gap
        gaps.append(min(gap, max_gap))
    return gaps


def _group_row(
    pts: np.ndarray, members: np.ndarray, solid: np.ndarray, opt: ContextOptions
) -> np.ndarray:
    """(13,) the group columns of the points `members` (N,) bool."""
    own = pts[members]
    lo, hi = own.min(axis=0), own.max(axis=0)
    span = hi - lo
    gaps = _gaps(pts, ~members & solid, lo, hi, opt.max_gap)
    floor = pts[~solid]
    seen = []
    for side, across, edge in _box_sides(floor[:, 0], floor[:, 1], lo, hi):
        strip = across & (side > edge) & (side <= edge + opt.clearance)
        seen.append(np.log10(1.0 + np.count_nonzero(strip)))
    return np.array([np.log10(len(own)), *span, hi[2], *gaps, *seen])
