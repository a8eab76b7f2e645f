"""Exact marginals of an affordance map through gtsam, one connected component at a time.

Exact inference costs grow exponentially with a component's treewidth. A greedy
min-degree elimination gives an upper bound on it (`elimination_width`); components whose
bound exceeds ``max_width`` are refused with an error pointing at belief propagation. With
the default ``max_width = 10`` a fully occupied 8x8 map (min-degree width 10, about 0.15 s
per direction in gtsam) is still solved exactly while 9x9 (width 12, about 1.7 s; 12x12
takes close to a minute) is not.
"""

from __future__ import annotations

import heapq
from collections.abc import Sequence
from typing import Any

import gtsam
import numpy as np
import torch

from probaff._checks import check_count
from probaff.errors import InputError
from probaff.maps.components import edge_array
from probaff.maps.evidence import as_evidence
from probaff.maps.graph import AffordanceGraph

__all__ = [
    "DEFAULT_MAX_EXACT_WIDTH",
    "MAX_WIDTH_SCAN_VARIABLES",
    "component_widths",
    "elimination_width",
    "exact_marginals",
]

DEFAULT_MAX_EXACT_WIDTH = 10
"""Largest min-degree elimination width solved exactly (cliques of ``2**11`` entries)."""

MAX_WIDTH_SCAN_VARIABLES = 10_000
"""Cyclic components larger than this are not scanned (the scan is a Python loop); their
width is reported as the trivial bound ``n - 1``."""


def elimination_width(num_variables: int, edges: np.ndarray, *, limit: int | None = None) -> int:
    """Width of a greedy min-degree elimination order, an upper bound on the treewidth.

    Args:
        num_variables: Number of variables ``n`` (indices ``0..n-1``), an integer >= 0.
        edges: ``(E, 2)`` variable pairs.
        limit: Stop as soon as the width exceeds this value (the returned value is then
            only known to be ``> limit``); an integer >= 0, or None for no limit.

    Returns:
        The largest number of neighbours a variable had when it was eliminated (0 for
        isolated variables, 1 for forests).

    Raises:
        InputError: If `num_variables` or `limit` is not an integer >= 0, or for `edges` that
            are not ``(E, 2)`` integer indices in ``[0, n)``.
    """
    num_variables = check_count("num_variables", num_variables, minimum=0)
    if limit is not None:
        limit = check_count("limit", limit, minimum=0)
    edges = edge_array("edges", edges, num_variables)
    if edges.shape[0] == 0:
        return 0
    adjacency: list[set[int]] = [set() for _ in range(num_variables)]
    for a, b in edges.tolist():
        if a != b:
            adjacency[a].add(b)
            adjacency[b].add(a)
    heap = [(len(nbrs), v) for v, nbrs in enumerate(adjacency)]
    heapq.heapify(heap)
    eliminated = [False] * num_variables
    width = 0
    while heap:
        degree, v = heapq.heappop(heap)
        if eliminated[v] or degree != len(adjacency[v]):
            continue
        width = max(width, degree)
        if limit is not None and width > limit:
            return width
        eliminated[v] = True
        neighbours = adjacency[v]
        adjacency[v] = set()
        for u in neighbours:
            adjacency[u].discard(v)
            adjacency[u].update(w for w in neighbours if w != u)
        for u in neighbours:
            heapq.heappush(heap, (len(adjacency[u]), u))
    return width


def component_widths(
    graph: AffordanceGraph,
    components: Sequence[int] | None = None,
    *,
    limit: int | None = None,
) -> tuple[int, ...]:
    """Min-degree elimination width of components of `graph`.

    Args:
        graph: The affordance map.
        components: Indices into ``graph.components``; all when None.
        limit: Passed to `elimination_width` (values above it are lower bounds only); an
            integer >= 0, or None.

    Returns:
        One width per selected component: 0 for a single variable, 1 for a tree, ``n - 1``
        for a cyclic component of more than `MAX_WIDTH_SCAN_VARIABLES` variables, else the
        min-degree elimination width.

    Raises:
        InputError: On an unknown component index, or a `limit` that is not an integer >= 0.
    """
    if limit is not None:
        limit = check_count("limit", limit, minimum=0)
    selected = _check_components(graph, components)
    widths = []
    for k in selected:
        variables, edge_ids = graph.components[k], graph.component_edge_ids[k]
        if variables.size == 1 or edge_ids.size == variables.size - 1:
            widths.append(min(1, int(variables.size) - 1))
            continue
        if variables.size > MAX_WIDTH_SCAN_VARIABLES:
            widths.append(int(variables.size) - 1)
            continue
        local = np.searchsorted(variables, graph.edges[edge_ids])
        widths.append(elimination_width(int(variables.size), local, limit=limit))
    return tuple(widths)


def _component_marginals(graph: AffordanceGraph, k: int, clamp: dict[int, int]) -> np.ndarray:
    """``(n, 2)`` exact marginals of component `k` given ``{variable: value}`` evidence."""
    marginals = gtsam.DiscreteMarginals(graph.to_gtsam(k, clamp))
    return np.stack([marginals.marginalProbabilities((int(v), 2)) for v in graph.components[k]])


def _check_components(graph: AffordanceGraph, components: Sequence[int] | None) -> list[int]:
    count = len(graph.components)
    if components is None:
        return list(range(count))
    selected = [int(k) for k in components]
    bad = [k for k in selected if not 0 <= k < count]
    if bad:
        raise InputError(f"components {bad[:5]} do not exist; the map has {count} components.")
    return selected


def exact_marginals(
    graph: AffordanceGraph,
    evidence: Any = None,
    *,
    max_width: int = DEFAULT_MAX_EXACT_WIDTH,
    components: Sequence[int] | None = None,
) -> torch.Tensor:
    """Exact marginals with gtsam (`gtsam.DiscreteMarginals`), per connected component.

    Each component is solved once without evidence; for every evidence row only the
    components holding a clamped variable are solved again.

    Args:
        graph: The affordance map.
        evidence: None, ``(V,)`` or ``(B, V)`` values in {-1 (free), 0, 1}.
        max_width: Refuse components whose min-degree elimination width exceeds this (an
            integer >= 0).
        components: Indices into ``graph.components`` to solve; all when None. Variables of
            other components are left NaN.

    Returns:
        float64 ``(V, 2)`` marginals ``(P(x=0), P(x=1))``, or ``(B, V, 2)`` for batched
        evidence.

    Raises:
        InputError: If a selected component is too wide for exact inference, on malformed
            evidence, or if `max_width` is not an integer >= 0.
    """
    max_width = check_count("max_width", max_width, minimum=0)
    ev, batched = as_evidence(evidence, (graph.num_variables,))
    selected = _check_components(graph, components)
    widths = component_widths(graph, selected, limit=max_width)
    for k, width in zip(selected, widths, strict=True):
        if width > max_width:
            size = int(graph.components[k].size)
            raise InputError(
                f"component {k} ({size} variables; its elimination width exceeds "
                f"max_width={max_width}) is too large for exact inference: gtsam would build "
                f"tables of more than "
                f"2**{max_width + 1} entries and may run for minutes. Use method='bp' (loopy "
                "belief propagation) or method='auto', or raise max_width."
            )
    out = np.full((ev.shape[0], graph.num_variables, 2), np.nan)
    wanted = set(selected)
    for k in selected:
        variables = graph.components[k]
        out[:, variables] = _component_marginals(graph, k, {})
    ev_np = ev.numpy()
    for b in range(ev.shape[0]):
        clamped = np.flatnonzero(ev_np[b] >= 0)
        touched = set(np.unique(graph.component_index[clamped]).tolist())
        for k in sorted(touched & wanted):
            variables = graph.components[k]
            clamp = {int(v): int(ev_np[b, v]) for v in variables if ev_np[b, v] >= 0}
            out[b, variables] = _component_marginals(graph, k, clamp)
    result = torch.from_numpy(out)
    return result if batched else result[0]
