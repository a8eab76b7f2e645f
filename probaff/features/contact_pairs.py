"""The bounded search for (actor, target) point pairs that can touch along an action.

`probaff.features.ch6.interaction_features` moves an actor's points along A_t's y and asks,
for each of them, which target points come within the contact distance r_d on the way, and
how soon. Checking every pair costs P x Q per interaction; this module returns the candidate
pairs only: a touch bound first (the smallest distance along the action at which some actor
point can come within r_d, from coarse cells of the points' positions across the action),
then the pairs that lie within r_d across the action and within a window along it, found
through grids of cells of r_d / `_U_CELLS` across the action. Pairs left out provably change
neither the touch distance nor the contact. Run lookups use cumulative tables, dense where
the grid is small enough and sorted otherwise. The result is exact against the brute-force
search (tests/features/test_features_ch6.py).

All coordinates are in the action frame A_t (m): x off-action, y along it, z up.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from probaff.errors import InputError

__all__ = ["BOUNDARY_TOL", "CandidatePairs", "candidate_pairs"]

_U_CELLS = 4  # cells per contact distance along u in the grid that finds close pairs
BOUNDARY_TOL = 1e-9  # m; coordinates this close below a cell boundary count as on it
"""Coordinates this close below a cell boundary count as on it (m)."""
_BOUND_CELL = 0.7  # cell edge of the touch bound in units of r_d (below 1 / sqrt(2))
_DENSE_CELLS = 1 << 16  # grids up to this many cells, or
_DENSE_CELLS_PER_POINT = 8  # this many per point, are held as dense tables


@dataclass(frozen=True)
class CandidatePairs:
    """(target point, actor point) pairs whose paths come within r_d during the action.

    Attributes:
        target: (K,) flat index ``n * P + i`` of the target point.
        actor: (K,) flat index ``n * Q + j`` of the actor point.
        sample: (K,) sample n.
        along: (K,) offset target - actor along A_t's y (m).
        across2: (K,) squared offset across the action, in A_t's (x, z) (m^2).
    """

    target: np.ndarray
    actor: np.ndarray
    sample: np.ndarray
    along: np.ndarray
    across2: np.ndarray


def _plane_cells(
    uv: np.ndarray, sample: np.ndarray, size: float, origin: np.ndarray, margin: int
) -> tuple[np.ndarray, np.ndarray]:
    """(K,) integer cells ``(cu, cv)`` of plane points, counted from their sample's origin.

    Args:
        uv: (2, K) plane coordinates (m).
        sample: (K,) their samples.
        size: Cell edge (m).
        origin: (N, 2) per sample, the cell of its lowest corner.
        margin: Cells left free below the origin.
    """
    cu = np.floor(uv[0] / size).astype(np.int64) - origin[sample, 0] + margin
    cv = np.floor(uv[1] / size).astype(np.int64) - origin[sample, 1] + margin
    return cu, cv


def _dense(cells: int, points: int) -> bool:
    """Whether a grid of `cells` cells over all samples is small enough to hold densely."""
    return cells <= max(_DENSE_CELLS, _DENSE_CELLS_PER_POINT * points)


def _near_across(
    hashed: np.ndarray,
    sample_h: np.ndarray,
    queries: np.ndarray,
    sample_q: np.ndarray,
    r: float,
    low: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Pairs of points of the same sample closer than `r` in a plane.

    The hashed points go into a grid over all samples at once, of rows r high in v and cells
    ``r / _U_CELLS`` wide in u, sorted by cell, so that each row's cells are consecutive. A
    point closer than r to a query lies in the query's row or one of its two neighbours,
    within ``u_q +- r``: three runs of consecutive cells, whose ends are read from a dense
    table of cumulative counts (or, for grids too large to hold, by binary search). The
    candidates are then measured.

    Args:
        hashed: (2, M) plane coordinates ``(u, v)`` of the points put in the grid (m).
        sample_h: (M,) their samples.
        queries: (2, K) plane coordinates of the points that look up their neighbours (m).
        sample_q: (K,) their samples.
        r: Distance (m).
        low: (N, 2) per sample, a lower bound of the coordinates of all its points (m).

    Returns:
        ``(i, j, d2)``: indices into `hashed` and `queries` of each pair closer than `r`, and
        their squared distance.
    """
    size_u = r / _U_CELLS
    margin = _U_CELLS + 2  # cells below the lowest point, for the runs that start there
    ou = np.floor(low[:, 0] / size_u).astype(np.int64) - margin  # (N,) first cell in u
    ov = np.floor(low[:, 1] / r).astype(np.int64) - 1  # (N,) first row
    cu_h = np.floor(hashed[0] / size_u).astype(np.int64) - ou[sample_h]
    cv_h = np.floor(hashed[1] / r).astype(np.int64) - ov[sample_h]
    half = r * (1.0 + BOUNDARY_TOL)  # runs a hair wider than r, against rounding
    first = np.floor((queries[0] - half) / size_u).astype(np.int64) - ou[sample_q]
    last = np.floor((queries[0] + half) / size_u).astype(np.int64) - ou[sample_q]
    cv_q = np.floor(queries[1] / r).astype(np.int64) - ov[sample_q]
    wu = int(max(cu_h.max(initial=0), last.max(initial=0))) + 2
    wv = int(max(cv_h.max(initial=0), cv_q.max(initial=0))) + 2
    cells = int(low.shape[0]) * wu * wv
    if cells.bit_length() > 62:
        raise InputError(
            "the points of one sample span too many contact cells to index; they lie "
            "implausibly far apart (check that their units are metres)."
        )
    key_h = (sample_h * wv + cv_h) * wu + cu_h
    order = np.argsort(key_h)
    hu, hv = hashed[0][order], hashed[1][order]  # sorted by cell, for local reads below
    rows = ((sample_q * wv + cv_q) * wu)[None, :] + np.array([-wu, 0, wu])[:, None]  # (3, K)
    if _dense(cells, key_h.size):
        before = np.zeros(cells + 1, dtype=np.int64)  # hashed points in all cells before each
        np.cumsum(np.bincount(key_h, minlength=cells), out=before[1:])
        start, stop = before[rows + first], before[rows + last + 1]
    else:
        key_s = key_h[order]
        start, stop = np.searchsorted(key_s, rows + first), np.searchsorted(key_s, rows + last + 1)
    k = (stop - start).ravel()
    busy = np.flatnonzero(k)
    k, start = k[busy], start.ravel()[busy]
    slot = np.arange(int(k.sum())) - np.repeat(np.cumsum(k) - k, k) + np.repeat(start, k)
    qi = np.repeat(busy % queries.shape[1], k)
    d2 = (hu[slot] - queries[0][qi]) ** 2 + (hv[slot] - queries[1][qi]) ** 2
    near = d2 < r * r
    return order[slot[near]], qi[near], d2[near]


def _touch_bound(
    t_uv: np.ndarray,
    t_y: np.ndarray,
    t_sample: np.ndarray,
    a_uv: np.ndarray,
    a_y: np.ndarray,
    a_sample: np.ndarray,
    length: np.ndarray,
    r: float,
    low: np.ndarray,
) -> np.ndarray:
    """(N,) an upper bound of each sample's first touch before clamping, ``inf`` if none found.

    The points go into cells of ``_BOUND_CELL r`` across the action, whose diagonal is below r,
    so a target point and an actor point that share a cell are closer than r across. In every
    cell that holds both, the rearmost target point and the frontmost actor point are such a
    pair; when their offset along the action, ``w_y``, lies in ``[0, length]`` the pair meets
    during the action (``w_y + h >= 0`` and ``w_y - h <= length`` for ``h > 0``). The touch
    ``w_y - h`` of the pair with the least ``w_y`` in a sample is then at least that sample's
    least touch over all pairs.

    Args:
        t_uv: (2, K) target points across the action, A_t's (x, z) (m).
        t_y: (K,) their coordinates along the action (m).
        t_sample: (K,) their samples.
        a_uv: (2, M) actor points across the action (m).
        a_y: (M,) their coordinates along the action (m).
        a_sample: (M,) their samples.
        length: (N,) action lengths (m).
        r: Contact distance r_d (m).
        low: (N, 2) per sample, a lower bound of the across coordinates of all its points (m).
    """
    n = low.shape[0]
    size = _BOUND_CELL * r
    origin = np.floor(low / size).astype(np.int64)
    cu_t, cv_t = _plane_cells(t_uv, t_sample, size, origin, 0)
    cu_a, cv_a = _plane_cells(a_uv, a_sample, size, origin, 0)
    wu = int(max(cu_t.max(initial=0), cu_a.max(initial=0))) + 1
    wv = int(max(cv_t.max(initial=0), cv_a.max(initial=0))) + 1
    cells = n * wu * wv
    if cells.bit_length() > 62:
        return np.full(n, np.inf)  # no bound: the pair search then covers the whole action
    key_t = (t_sample * wv + cv_t) * wu + cu_t
    key_a = (a_sample * wv + cv_a) * wu + cu_a
    if _dense(cells, t_y.size + a_y.size):
        rear = np.full(cells, np.inf)
        np.minimum.at(rear, key_t, t_y)
        front = np.full(cells, -np.inf)
        np.maximum.at(front, key_a, a_y)
        along = (rear - front).reshape(n, wu * wv)  # inf where a cell lacks either
        along[(along < 0.0) | (along > length[:, None])] = np.inf
        best = np.argmin(along, axis=1) + np.arange(n) * (wu * wv)  # (N,) key of the best cell
        w_y, rear, front = along.ravel()[best], rear[best], front[best]
    else:
        keys, rear_k = _group_extreme(key_t, t_y, np.minimum)
        keys_a, front_k = _group_extreme(key_a, a_y, np.maximum)
        pos = np.minimum(np.searchsorted(keys_a, keys), keys_a.size - 1)
        along = np.where(keys_a[pos] == keys, rear_k - front_k[pos], np.inf)
        sample = keys // (wu * wv)
        along[(along < 0.0) | (along > length[sample])] = np.inf
        w_y = np.full(n, np.inf)
        np.minimum.at(w_y, sample, along)
        pick = np.flatnonzero(np.isfinite(along) & (along == w_y[sample]))
        pick = pick[np.unique(sample[pick], return_index=True)[1]]  # one best cell per sample
        best = np.full(n, -1)
        best[sample[pick]] = keys[pick]
        rear, front = np.zeros(n), np.zeros(n)
        rear[sample[pick]] = rear_k[pick]
        front[sample[pick]] = front_k[pos[pick]]
    # one target and one actor point that attain the best cell's extremes
    pick_t, pick_a = np.zeros(n, dtype=np.int64), np.zeros(n, dtype=np.int64)
    hit = np.flatnonzero((key_t == best[t_sample]) & (t_y == rear[t_sample]))
    pick_t[t_sample[hit]] = hit
    hit = np.flatnonzero((key_a == best[a_sample]) & (a_y == front[a_sample]))
    pick_a[a_sample[hit]] = hit
    across2 = ((t_uv[:, pick_t] - a_uv[:, pick_a]) ** 2).sum(axis=0)
    h = np.sqrt(np.maximum(r * r - across2, 0.0))
    return np.where(np.isfinite(w_y), w_y - h, np.inf)


def _group_extreme(
    key: np.ndarray, value: np.ndarray, op: np.ufunc
) -> tuple[np.ndarray, np.ndarray]:
    """Distinct keys, sorted, and the extreme (`op`: minimum or maximum) of the values of each.

    Args:
        key: (K,) integer keys, K >= 1.
        value: (K,) values.
        op: ``np.minimum`` or ``np.maximum``.
    """
    order = np.argsort(key)
    key = key[order]
    first = np.flatnonzero(np.r_[True, key[1:] != key[:-1]])
    return key[first], op.reduceat(value[order], first)


def candidate_pairs(
    obj: np.ndarray, act: np.ndarray, length: np.ndarray, r: float
) -> CandidatePairs:
    """Every (target, actor) pair that can give the first touch or be a contact pair.

    Only target points inside the actor's swept box (grown by r) and actor points inside the
    target's box (grown by r and stretched back by the length) can meet. Of the pairs that
    meet during the action, only those whose offset along the action, ``w_y``, is at most
    ``reach = max(bound, 0) + 1.5 r`` matter, where ``bound`` (`_touch_bound`) is at least the
    touch ``s`` before clamping: the pair that gives ``s`` has ``w_y = s + h <= bound + r``, and
    a contact pair, closer than r to the actor moved by ``min(max(s, 0) + r / 2, length)``, has
    ``w_y < max(bound, 0) + 1.5 r``. Every other pair changes no output, so the points are
    filtered once more with the reach in place of the length, which drops most of the faces
    that slide past each other (the coplanar tops and sides of boxes in a row). The larger set
    is then hashed into a grid across the action (A_t's x, z) and the smaller looks up its
    neighbours there.

    Args:
        obj: (3, N, P) target points in A_t.
        act: (3, N, Q) actor points in A_t, at the start.
        length: (N,) action lengths (m).
        r: Contact distance r_d (m).
    """
    n, p = obj.shape[1:]
    q = act.shape[2]
    lo_o, hi_o = obj.min(axis=2), obj.max(axis=2)  # (3, N)
    lo_a, hi_a = act.min(axis=2), act.max(axis=2)
    front = hi_a[1].copy()  # (N,) the actor's frontmost coordinate along the action
    lo_a, hi_a = lo_a - r, hi_a + r
    hi_a[1] += length
    lo_t, hi_t = lo_o - r, hi_o + r
    lo_t[1] -= length
    obj_ok = np.ones((n, p), dtype=bool)
    act_ok = np.ones((n, q), dtype=bool)
    for axis in range(3):
        obj_ok &= (obj[axis] >= lo_a[axis, :, None]) & (obj[axis] <= hi_a[axis, :, None])
        act_ok &= (act[axis] >= lo_t[axis, :, None]) & (act[axis] <= hi_t[axis, :, None])
    t_flat, a_flat = np.flatnonzero(obj_ok), np.flatnonzero(act_ok)
    empty = np.zeros(0, dtype=np.int64)
    if t_flat.size == 0 or a_flat.size == 0:
        return CandidatePairs(empty, empty, empty, np.zeros(0), np.zeros(0))

    ox, oy, oz = obj.reshape(3, -1)
    ax, ay, az = act.reshape(3, -1)
    low = lo_t[[0, 2]].T  # (N, 2) below every point that passed
    t_sample, a_sample = t_flat // p, a_flat // q
    bound = _touch_bound(
        np.stack([ox[t_flat], oz[t_flat]]),
        oy[t_flat],
        t_sample,
        np.stack([ax[a_flat], az[a_flat]]),
        ay[a_flat],
        a_sample,
        length,
        r,
        low,
    )
    # (N,) the reach, widened by a rounding margin; where there is no bound it only repeats
    # the test of the boxes above (a pair meets before the action ends only if w_y <= L + r)
    reach = np.minimum(length + r, np.maximum(bound, 0.0) + 1.5 * r) + BOUNDARY_TOL
    t_flat = t_flat[oy[t_flat] <= front[t_sample] + reach[t_sample]]
    a_flat = a_flat[ay[a_flat] >= lo_o[1, a_sample] - reach[a_sample]]
    if t_flat.size == 0 or a_flat.size == 0:
        return CandidatePairs(empty, empty, empty, np.zeros(0), np.zeros(0))

    t_uv, t_sample = np.stack([ox[t_flat], oz[t_flat]]), t_flat // p
    a_uv, a_sample = np.stack([ax[a_flat], az[a_flat]]), a_flat // q
    if a_flat.size >= t_flat.size:
        ia, it, across2 = _near_across(a_uv, a_sample, t_uv, t_sample, r, low)
    else:
        it, ia, across2 = _near_across(t_uv, t_sample, a_uv, a_sample, r, low)
    target, actor = t_flat[it], a_flat[ia]
    along = oy[target] - ay[actor]
    sample = target // p
    h = np.sqrt(r * r - across2)
    keep = (along + h >= 0.0) & (along - h <= length[sample]) & (along <= reach[sample])
    return CandidatePairs(target[keep], actor[keep], sample[keep], along[keep], across2[keep])
