"""Helpers of the affordance-map tests: map generators and independent references."""

from __future__ import annotations

import math

import gtsam
import numpy as np

from probaff.maps import AffordanceGraph
from probaff.maps.synthetic import drop_shelves


def sparse_map(rng: np.random.Generator, size: int = 12, lo: int = 10, hi: int = 30) -> np.ndarray:
    """Boxes dropped uniformly at random: mostly isolated boxes and small clusters."""
    occ = np.zeros(size * size, dtype=bool)
    occ[rng.choice(size * size, int(rng.integers(lo, hi + 1)), replace=False)] = True
    return occ.reshape(size, size)


def shelf_map(rng: np.random.Generator, size: int = 12, lo: int = 10, hi: int = 30) -> np.ndarray:
    """Boxes stacked in 1- or 2-deep shelves: many short cycles."""
    while True:
        occ = drop_shelves(rng, size, int(rng.integers(lo, hi + 1)))
        if occ.sum() <= hi:
            return occ


def reference_factor_graph(
    graph: AffordanceGraph, clamp: dict[int, int] | None = None
) -> gtsam.DiscreteFactorGraph:
    """gtsam graph written directly from the map definition, independent of `to_gtsam`."""
    occ, unary = graph.occupancy, graph.unary
    height, width = occ.shape
    clamp = clamp or {}
    fg = gtsam.DiscreteFactorGraph()
    for r, c in zip(*np.nonzero(occ), strict=True):
        for d in range(4):
            key = graph.variable(int(r), int(c), d)
            p = float(unary[r, c, d])
            table = [1.0 - p, p] if key not in clamp else [1.0 - clamp[key], float(clamp[key])]
            fg.add((key, 2), table)

    def pair(k1: int, k2: int, strength: float) -> None:
        a, b = math.exp(strength), math.exp(-strength)
        fg.add([(k1, 2), (k2, 2)], [a, b, b, a])

    for r in range(height):
        for c in range(width):
            if not occ[r, c]:
                continue
            for dr, dc in ((1, 0), (0, 1)):
                rr, cc = r + dr, c + dc
                if rr < height and cc < width and occ[rr, cc]:
                    along = (0, 1) if dr else (2, 3)  # up/down lie along a column
                    for d in range(4):
                        j = graph.along_coupling if d in along else graph.coupling
                        pair(graph.variable(r, c, d), graph.variable(rr, cc, d), j)
            if graph.symmetry_coupling is not None:
                if r > 0 and occ[r - 1, c]:  # up of this cell, down of the cell above
                    pair(
                        graph.variable(r, c, "up"),
                        graph.variable(r - 1, c, "down"),
                        graph.symmetry_coupling,
                    )
                if c > 0 and occ[r, c - 1]:  # left of this cell, right of the cell left of it
                    pair(
                        graph.variable(r, c, "left"),
                        graph.variable(r, c - 1, "right"),
                        graph.symmetry_coupling,
                    )
    return fg


def reference_marginals(graph: AffordanceGraph, clamp: dict[int, int] | None = None) -> np.ndarray:
    """``(V, 2)`` exact marginals of the whole map straight from `gtsam.DiscreteMarginals`."""
    marginals = gtsam.DiscreteMarginals(reference_factor_graph(graph, clamp))
    return np.stack([marginals.marginalProbabilities((v, 2)) for v in range(graph.num_variables)])


def reference_loopy_bp(
    unary: np.ndarray, edges: np.ndarray, pairwise: np.ndarray, iters: int = 2000
) -> np.ndarray:
    """Textbook probability-domain sum-product with a loop over edges (small graphs only).

    Args:
        unary: ``(V, 2)`` potentials. edges: ``(E, 2)``. pairwise: ``(E, 2, 2)`` potentials.
    """
    num_vars = unary.shape[0]
    msgs = {}
    for e, (a, b) in enumerate(edges.tolist()):
        msgs[(e, a, b)] = np.full(2, 0.5)
        msgs[(e, b, a)] = np.full(2, 0.5)
    incoming: list[list[tuple[int, int, int]]] = [[] for _ in range(num_vars)]
    for key in msgs:
        incoming[key[2]].append(key)
    for _ in range(iters):
        new = {}
        for e, i, j in msgs:
            belief = unary[i].copy()
            for key in incoming[i]:
                if key[1] != j or key[0] != e:
                    belief = belief * msgs[key]
            table = pairwise[e] if i == edges[e, 0] else pairwise[e].T  # [x_i, x_j]
            m = belief @ table
            new[(e, i, j)] = 0.5 * msgs[(e, i, j)] + 0.5 * m / m.sum()
        delta = max(np.abs(new[k] - msgs[k]).max() for k in msgs) if msgs else 0.0
        msgs = new
        if delta < 1e-14:
            break
    out = unary.copy()
    for v in range(num_vars):
        for key in incoming[v]:
            out[v] = out[v] * msgs[key]
    return out / out.sum(axis=1, keepdims=True)
