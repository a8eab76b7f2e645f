"""Region-growing segmentation of a point cloud with the semantics of PCL's ``RegionGrowing``.

Chapter 2 cuts the cloud into smooth surface patches with PCL's region growing. This module
follows PCL's algorithm:

1. Every valid point gets its ``k`` nearest neighbours (one ``cKDTree`` query, the point
   itself included, as PCL's ``setNumberOfNeighbours``).
2. Points are visited in order of increasing curvature; the first unlabelled one starts a new
   region as its initial seed.
3. For each seed of the region, each unlabelled neighbour joins the region when the angle
   between its normal and the *current seed's* normal is below the smoothness angle
   (``|n_seed . n_neighbour| >= cos(angle)``; the absolute value, as PCL takes it, makes the
   test blind to the normals' sign). A neighbour that joined becomes a seed itself only when
   its curvature is not above the curvature threshold; otherwise it stays in the region but does
   not grow it.
4. A region with fewer than ``min_size`` points is dropped: its points are unassigned (-1)
   and it is counted in `Segmentation.n_small`.

One region is grown to completion before the next one starts, so the set of points a region
takes does not depend on the order its seeds are expanded in. When every point may seed (the
default curvature threshold, above every surface variation), the regions follow from the
directed graph of smooth links (point -> each neighbour that passes the smoothness test) without
growing them one by one: a point ends in the region of the first point, in curvature order,
among the points it can be reached from (that point starts a region, since no earlier start
reaches it, and no earlier start reaches the point). The graph's strongly connected components
(``scipy.sparse.csgraph``) share their reachers, so this first reacher is a minimum propagated
over the few links between components. With a lower threshold, points that may not seed end
the growth, and the regions are grown one at a time (as they are for given neighbour lists that
name one neighbour twice, on which scipy's components do not return): one breadth-first level
at a time, a small level point by point over Python lists (cheap for the many tiny regions of
a noisy scan), a large one in one numpy step. Both give the same segments.

Frames and units: points in the robot frame (x forward, z up), metres; normals unit vectors in
that frame; curvature is PCL's surface variation (`probaff.perception.normals`).

Thresholds and defaults (chapter 2 / PCL):
    k = 30 neighbours, smoothness 3 degrees, curvature 1.0, minimum region 50 points: the
        values of PCL's region-growing tutorial, which the thesis uses. Surface variation never
        exceeds 1/3, so the default curvature threshold lets every point seed (as in PCL,
        where it is known to have no effect at its default); a lower one stops growth across
        edges and curved parts, whose curvature exceeds that of planes.

Points with a NaN coordinate, normal or curvature are unassigned (-1) and counted in
`Segmentation.n_invalid`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from probaff._checks import as_float_array, check_count, check_positive, check_shape
from probaff.errors import InputError

__all__ = ["Segmentation", "region_growing"]

_SMALL_FRONTIER = 32  # frontiers smaller than this are expanded in Python, larger in numpy
_MAX_PASSES = 64  # passes of the first reacher between components before `_grow` takes over


@dataclass(frozen=True)
class Segmentation:
    """The result of region growing.

    Attributes:
        labels: (N,) int64 segment of each point, ``0 .. n_segments - 1`` in the order the
            regions were grown (increasing seed curvature), -1 for unassigned points.
        n_segments: Number of kept segments.
        n_small: Number of regions dropped for having fewer than ``min_size`` points.
        n_invalid: Number of points skipped for a NaN coordinate or normal.
    """

    labels: np.ndarray
    n_segments: int
    n_small: int
    n_invalid: int


def _validate(
    points: ArrayLike, normals: ArrayLike, curvature: ArrayLike
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Check the inputs.

    Returns:
        The (N, 3) points, (N, 3) normals and (N,) curvature as float arrays, the (N,) mask of
        usable rows (no NaN) and the (N,) lengths of the normals.
    """
    pts = as_float_array("points", points)
    nrm = as_float_array("normals", normals)
    cur = as_float_array("curvature", curvature)
    check_shape("points", pts, (None, 3))
    n = len(pts)
    if n == 0:
        raise InputError("points is an empty cloud; give at least one point of shape (N, 3).")
    check_shape("normals", nrm, (n, 3))
    check_shape("curvature", cur, (n,))
    arrays = (("points", pts), ("normals", nrm), ("curvature", cur))
    finite = [np.isfinite(arr) for _, arr in arrays]
    for (name, arr), fin in zip(arrays, finite, strict=True):
        if not fin.all() and np.isinf(arr).any():
            raise InputError(f"{name} contains infinite values; replace them with NaN or remove.")
    fp, fn, fc = finite  # without infinities, finite means without NaN
    valid = fp[:, 0] & fp[:, 1] & fp[:, 2] & fn[:, 0] & fn[:, 1] & fn[:, 2] & fc
    if not valid.any():
        raise InputError(
            "points, normals and curvature have no row without NaN; give finite points and "
            "their normals from estimate_normals."
        )
    length = np.linalg.norm(nrm, axis=1)
    flat = np.flatnonzero(valid & (length < 1e-9))
    if flat.size:
        raise InputError(
            f"normals has {flat.size} row(s) of zero length (the first is row {flat[0]}); give "
            "unit normals, e.g. from estimate_normals, or NaN for a point without one."
        )
    return pts, nrm, cur, valid, length


def _given_neighbours(
    neighbours: ArrayLike, valid: np.ndarray, keep: np.ndarray, k: int
) -> tuple[np.ndarray, np.ndarray]:
    """Map given neighbour lists onto the valid points.

    Args:
        neighbours: (N, K) indices into the cloud's rows, -1 for none.
        valid: (N,) usable rows of the cloud.
        keep: (M,) indices of the usable rows.
        k: Neighbours to use (K >= k).

    Returns:
        (M, k) neighbour indices into the usable points (0 where there is none) and the
        (M, k) mask of real links.
    """
    arr = np.asarray(neighbours)
    n = len(valid)
    check_shape("neighbours", arr, (n, None))
    if arr.size and not np.issubdtype(arr.dtype, np.integer):
        raise InputError(
            f"neighbours must hold integer point indices, got dtype {arr.dtype}; pass "
            "Normals.neighbours from estimate_normals."
        )
    if arr.shape[1] < k:
        raise InputError(
            f"neighbours has {arr.shape[1]} column(s), fewer than k={k}; estimate the normals "
            "with at least k neighbours or lower k."
        )
    every = len(keep) == n
    sub = np.asarray(arr[:, :k] if every else arr[keep, :k], dtype=np.int64)
    low = int(sub.min()) if sub.size else 0
    if sub.size and (low < -1 or sub.max() >= n):
        raise InputError(f"neighbours must index rows 0..{n - 1} of points (or be -1).")
    if every and low >= 0:  # every row usable and linked: the indices are the points' own
        return sub, np.ones(sub.shape, dtype=bool)
    position = np.full(n + 1, -1, dtype=np.int64)  # the last slot answers index -1
    position[keep] = np.arange(len(keep))
    mapped = position[sub]
    linked = mapped >= 0
    mapped[~linked] = 0
    return mapped, linked


def _grow(
    nbrs: np.ndarray, smooth: np.ndarray, can_seed: np.ndarray, order: np.ndarray
) -> tuple[np.ndarray, list[int]]:
    """Grow regions over the neighbour graph.

    A small frontier is expanded point by point in Python, a large one in one numpy step;
    both give the same region, which does not depend on the expansion order.

    Args:
        nbrs: (M, k) neighbour indices of each point.
        smooth: (M, k) whether each neighbour passes the smoothness test with its point.
        can_seed: (M,) whether a point's curvature lets it become a seed.
        order: (M,) points in the order they may start a region.

    Returns:
        (M,) region index of every point and the size of each region.
    """
    flat = nbrs[smooth]
    offsets = np.concatenate([[0], np.cumsum(smooth.sum(axis=1))]).tolist()
    seeds = can_seed.tolist()
    region = np.full(len(nbrs), -1, dtype=np.int64)
    sizes: list[int] = []
    for start in order.tolist():
        if region[start] >= 0:
            continue
        r = len(sizes)
        region[start] = r
        size = 1
        frontier: list[int] = [start]
        while frontier:
            if len(frontier) < _SMALL_FRONTIER:
                grown: list[int] = []
                for s in frontier:
                    for j in flat[offsets[s] : offsets[s + 1]].tolist():
                        if region[j] < 0:
                            region[j] = r
                            size += 1
                            if seeds[j]:
                                grown.append(j)
                frontier = grown
                continue
            fr = np.asarray(frontier, dtype=np.int64)
            cand = nbrs[fr][smooth[fr]]
            cand = np.unique(cand[region[cand] < 0])
            region[cand] = r
            size += int(cand.size)
            frontier = cand[can_seed[cand]].tolist()
        sizes.append(size)
    return region, sizes


def _distinct(nbrs: np.ndarray, linked: np.ndarray) -> bool:
    """Whether no point lists one neighbour twice among its (M, k) linked `nbrs`.

    ``scipy.sparse.csgraph``'s strongly connected components do not return on a graph with a
    repeated link, so given neighbour lists with repeats are grown one region at a time.
    """
    if not linked.all():
        nbrs = np.where(linked, nbrs, -1 - np.arange(nbrs.shape[1]))  # distinct fillers
    ordered = np.sort(nbrs, axis=1)
    return not bool(np.any(ordered[:, 1:] == ordered[:, :-1]))


def _grow_all_seeds(
    nbrs: np.ndarray, smooth: np.ndarray, order: np.ndarray
) -> tuple[np.ndarray, np.ndarray] | None:
    """Grow regions when every point may seed, from the graph of smooth links.

    The region of a point is the one started by the first point in `order` among those it
    can be reached from (itself included) along smooth links, as the module docstring shows;
    the points of a strongly connected component share that first reacher, which is then
    passed down the links between components until it no longer changes. The result is the
    one of `_grow` with every point a seed. Each pass moves it one link further, so a graph
    whose components form a chain longer than `_MAX_PASSES` links (the office scans measured,
    with and without noise, at 3 to 15 degrees, needed at most 16 passes) is left to `_grow`,
    which is linear in the points.

    Args:
        nbrs: (M, k) neighbour indices of each point.
        smooth: (M, k) whether each neighbour passes the smoothness test with its point.
        order: (M,) points in the order they may start a region.

    Returns:
        (M,) region index of every point, regions numbered in the order their first point
        comes in `order`, and the (R,) size of each region; None after `_MAX_PASSES` passes.
    """
    m = len(nbrs)
    rank = np.empty(m, dtype=np.int64)
    rank[order] = np.arange(m)
    counts = np.count_nonzero(smooth, axis=1)
    indptr = np.zeros(m + 1, dtype=np.int64)
    np.cumsum(counts, out=indptr[1:])
    targets = nbrs[smooth]
    index = np.int32 if m < np.iinfo(np.int32).max else np.int64  # csgraph's own index type
    graph = csr_matrix(  # float64 links: the type csgraph works in, so it copies nothing
        (np.ones(len(targets)), targets.astype(index), indptr.astype(index)), shape=(m, m)
    )
    n_comp, comp = connected_components(graph, directed=True, connection="strong")
    first = np.full(n_comp, m, dtype=np.int64)
    np.minimum.at(first, comp, rank)
    src, dst = np.repeat(comp, counts), comp[targets]
    across = src != dst
    src, dst = src[across], dst[across]
    for _ in range(_MAX_PASSES + 1):  # as many passes as the longest chain of components
        if not src.size:
            break
        passed = first.copy()
        np.minimum.at(passed, dst, first[src])
        if np.array_equal(passed, first):
            break
        first = passed
    else:
        return None
    start = np.zeros(m, dtype=bool)  # by rank: whether that point starts a region
    start[first] = True
    region = (np.cumsum(start) - 1)[first[comp]]
    return region, np.bincount(region, minlength=int(np.count_nonzero(start)))


def region_growing(
    points: ArrayLike,
    normals: ArrayLike,
    curvature: ArrayLike,
    *,
    k: int = 30,
    smoothness_deg: float = 3.0,
    curvature_threshold: float = 1.0,
    min_size: int = 50,
    neighbours: ArrayLike | None = None,
) -> Segmentation:
    """Segment a cloud into smooth regions, as PCL's ``RegionGrowing`` does.

    Args:
        points: (N, 3) points in the robot frame (m); NaN rows are unassigned and counted.
        normals: (N, 3) unit normals of the points (e.g. from `estimate_normals`).
        curvature: (N,) surface variation of the points.
        k: Neighbours per point, the point itself included.
        smoothness_deg: Largest angle between a seed's and a neighbour's normal for the
            neighbour to join (degrees, in (0, 180)).
        curvature_threshold: A joined point becomes a seed only when its curvature is not
            above this (> 0).
        min_size: Regions with fewer points are dropped (label -1) and counted.
        neighbours: Optional (N, K) integer indices into the rows of `points` of each
            point's nearest neighbours, nearest first, with K >= k (`Normals.neighbours`);
            the first k columns are used and entries of -1 or of invalid points are ignored.
            By default they are found with one ``cKDTree`` query.

    Returns:
        The `Segmentation`: (N,) labels, the number of segments, of dropped regions and of
        invalid points.

    Raises:
        InputError: For an empty cloud, wrong shapes, infinities, a non-integer or
            non-positive `k` or `min_size`, a smoothness angle outside (0, 180) or a
            non-positive curvature threshold.
    """
    k = check_count("k", k)
    min_size = check_count("min_size", min_size)
    try:
        angle = float(smoothness_deg)
    except (TypeError, ValueError):
        raise InputError(f"smoothness_deg must be a number, got {smoothness_deg!r}.") from None
    if not 0.0 < angle < 180.0:
        raise InputError(
            f"smoothness_deg must lie in (0, 180) degrees, got {smoothness_deg!r}; PCL's "
            "default is 3."
        )
    check_positive("curvature_threshold", curvature_threshold)
    pts, nrm, cur, valid, length = _validate(points, normals, curvature)
    keep = np.flatnonzero(valid)
    if len(keep) == len(pts):  # every row usable: no copies
        p, nv, cv, norm = pts, nrm, cur, length
    else:
        p, nv, cv, norm = pts[keep], nrm[keep], cur[keep], length[keep]
    nv = nv / np.where(norm > 0, norm, 1.0)[:, None]
    if neighbours is None:
        kk = min(k, len(p))
        _, idx = cKDTree(p).query(p, k=kk)
        nbrs = np.asarray(idx, dtype=np.int64).reshape(len(p), kk)
        linked = np.ones(nbrs.shape, dtype=bool)
    else:
        nbrs, linked = _given_neighbours(neighbours, valid, keep, k)
    cos_thr = math.cos(math.radians(angle))
    # float32 halves the gathers and is ample for an angle test; one (M, k) gather per axis
    # beats one (M, k, 3) gather and an einsum
    nv32 = nv.astype(np.float32)
    dot = np.zeros(nbrs.shape, dtype=np.float32)
    for axis in range(3):
        column = np.ascontiguousarray(nv32[:, axis])
        dot += column[nbrs] * column[:, None]
    smooth = np.abs(dot) >= np.float32(cos_thr)
    smooth &= linked
    can_seed = cv <= float(curvature_threshold)
    order = np.argsort(cv, kind="stable")
    grown = None
    if can_seed.all() and (neighbours is None or _distinct(nbrs, linked)):
        grown = _grow_all_seeds(nbrs, smooth, order)
    if grown is None:
        region, sizes = _grow(nbrs, smooth, can_seed, order)
        size_arr = np.asarray(sizes, dtype=np.int64)
    else:
        region, size_arr = grown
    kept = size_arr >= min_size
    remap = np.full(len(size_arr), -1, dtype=np.int64)
    remap[kept] = np.arange(int(kept.sum()))
    labels = np.full(len(pts), -1, dtype=np.int64)
    labels[keep] = remap[region]
    return Segmentation(
        labels=labels,
        n_segments=int(kept.sum()),
        n_small=int((~kept).sum()),
        n_invalid=int(len(pts) - len(keep)),
    )
