"""Connected components of a pairwise graph, vectorised over edges (hook and compress)."""

from __future__ import annotations

import numpy as np

from probaff._checks import check_count

__all__ = ["component_labels", "group_components"]


def component_labels(num_nodes: int, edges: np.ndarray) -> np.ndarray:
    """Label every node with the smallest node index of its connected component.

    Roots are hooked onto the smaller root across every edge, then parent pointers are
    compressed until each node points at its root; this repeats until no edge joins two
    different roots. Each pass is a handful of vectorised numpy operations.

    Args:
        num_nodes: Number of nodes ``N`` (an integer >= 0).
        edges: ``(E, 2)`` integer node indices in ``[0, N)``.

    Returns:
        ``(N,)`` int64 labels; two nodes share a label iff they are connected.

    Raises:
        InputError: If `num_nodes` is not an integer >= 0.
    """
    num_nodes = check_count("num_nodes", num_nodes, minimum=0)
    parent = np.arange(num_nodes, dtype=np.int64)
    edges = np.asarray(edges, dtype=np.int64).reshape(-1, 2)
    if edges.shape[0] == 0:
        return parent
    src, dst = edges[:, 0], edges[:, 1]
    while True:
        root_src, root_dst = parent[src], parent[dst]
        crossing = root_src != root_dst
        if not crossing.any():
            return parent
        low = np.minimum(root_src[crossing], root_dst[crossing])
        high = np.maximum(root_src[crossing], root_dst[crossing])
        # `high` is a root (every node points at a root after compression); hooking it onto
        # a strictly smaller index can never create a cycle.
        np.minimum.at(parent, high, low)
        while True:
            grand = parent[parent]
            if np.array_equal(grand, parent):
                break
            parent = grand


def group_components(labels: np.ndarray) -> list[np.ndarray]:
    """Split node indices by component label.

    Args:
        labels: ``(N,)`` labels from `component_labels`.

    Returns:
        One sorted ``(n_k,)`` int64 index array per component, ordered by smallest member.
    """
    labels = np.asarray(labels, dtype=np.int64)
    if labels.size == 0:
        return []
    order = np.argsort(labels, kind="stable")
    sorted_labels = labels[order]
    starts = np.flatnonzero(np.r_[True, sorted_labels[1:] != sorted_labels[:-1]])
    return [np.ascontiguousarray(chunk) for chunk in np.split(order, starts[1:])]
