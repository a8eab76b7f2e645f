"""Connected components of a pairwise graph, vectorised over edges (hook and compress)."""

from __future__ import annotations

import numpy as np

from probaff._checks import as_real_array, check_count, check_shape
from probaff.errors import InputError

__all__ = ["component_labels", "edge_array", "group_components"]


def edge_array(name: str, edges: object, num_nodes: int) -> np.ndarray:
    """Return `edges` as ``(E, 2)`` int64 node pairs in ``[0, num_nodes)``, or raise.

    Args:
        name: The argument's name, for the message.
        edges: ``(E, 2)`` integer node indices (any array-like; an empty one is ``(0, 2)``).
        num_nodes: Number of nodes ``N``.

    Returns:
        ``(E, 2)`` int64 array.

    Raises:
        InputError: For edges that are not integers (floats, bools, strings, ragged lists),
            not ``(E, 2)``, or that name a node outside ``[0, N)``.
    """
    arr = as_real_array(name, edges)
    if arr.size == 0:
        return np.zeros((0, 2), dtype=np.int64)
    check_shape(name, arr, (None, 2))
    if arr.dtype.kind not in "iu":
        raise InputError(f"{name} must hold integer node indices, got dtype {arr.dtype}.")
    arr = arr.astype(np.int64, copy=False)
    if int(arr.min()) < 0 or int(arr.max()) >= num_nodes:
        raise InputError(
            f"{name} reference nodes outside [0, {num_nodes}): range "
            f"[{int(arr.min())}, {int(arr.max())}]."
        )
    return arr


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
        InputError: If `num_nodes` is not an integer >= 0, or for `edges` that are not
            ``(E, 2)`` integer indices in ``[0, N)``.
    """
    num_nodes = check_count("num_nodes", num_nodes, minimum=0)
    parent = np.arange(num_nodes, dtype=np.int64)
    edges = edge_array("edges", edges, num_nodes)
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

    Raises:
        InputError: For labels that are not a 1-D array of integers.
    """
    labels = as_real_array("labels", labels)
    if labels.size == 0:
        return []
    check_shape("labels", labels, (None,))
    if labels.dtype.kind not in "iu":
        raise InputError(f"labels must be integer component labels, got dtype {labels.dtype}.")
    order = np.argsort(labels, kind="stable")
    sorted_labels = labels[order]
    starts = np.flatnonzero(np.r_[True, sorted_labels[1:] != sorted_labels[:-1]])
    return [np.ascontiguousarray(chunk) for chunk in np.split(order, starts[1:])]
