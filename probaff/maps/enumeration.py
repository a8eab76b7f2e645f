"""Exact marginals of small components by enumeration, batched over evidence, in torch.

A component of n binary variables has 2**n joint states. Their log weights are computed once;
each distinct evidence pattern on the component masks the inconsistent states, and the
marginals follow from a softmax over the rest. For the components of a warehouse map (a few
boxes that touch, n <= 16) this is exact, like gtsam's elimination, and as batched as belief
propagation: thousands of conditioned copies cost one tensor program per component.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import torch

from probaff.errors import InputError
from probaff.maps.graph import AffordanceGraph

__all__ = ["MAX_ENUMERATION_VARIABLES", "enumerate_marginals"]

MAX_ENUMERATION_VARIABLES = 16
"""Largest component solved by enumeration (65,536 joint states)."""


def _component_log_weights(
    graph: AffordanceGraph, k: int, dtype: torch.dtype
) -> tuple[torch.Tensor, torch.Tensor]:
    """``(bits (S, n) bool, log_w (S,))`` of every joint state of component `k`."""
    variables = graph.components[k]
    n = int(variables.size)
    states = torch.arange(2**n)
    bits = ((states[:, None] >> torch.arange(n)) & 1).bool()  # (S, n)
    idx = bits.long()
    unary = graph.unary_log_potentials(dtype)[torch.from_numpy(variables)]  # (n, 2)
    log_w = unary.gather(1, idx.T).sum(0)  # (S,)
    edge_ids = graph.component_edge_ids[k]
    if edge_ids.size:
        local = torch.from_numpy(np.searchsorted(variables, graph.edges[edge_ids]))
        pair = graph.pairwise_log_potentials(dtype)[torch.from_numpy(edge_ids)]  # (e, 2, 2)
        xa, xb = idx[:, local[:, 0]], idx[:, local[:, 1]]  # (S, e)
        log_w = log_w + pair[torch.arange(len(edge_ids)), xa, xb].sum(1)
    return bits, log_w


def enumerate_marginals(
    graph: AffordanceGraph,
    evidence: torch.Tensor,
    components: Sequence[int],
    dtype: torch.dtype = torch.float64,
) -> torch.Tensor:
    """Exact marginals of the selected components under a batch of evidence.

    Args:
        graph: The affordance map.
        evidence: ``(B, V)`` int evidence (-1 free, 0 or 1 clamped).
        components: Indices into ``graph.components``, each with at most
            `MAX_ENUMERATION_VARIABLES` variables.
        dtype: Floating dtype of the computation and the result.

    Returns:
        ``(B, V, 2)`` marginals; variables outside the selected components are NaN.

    Raises:
        InputError: For a component that is too large to enumerate.
    """
    B, V = evidence.shape
    out = torch.full((B, V, 2), float("nan"), dtype=dtype)
    for k in components:
        variables = graph.components[k]
        n = int(variables.size)
        if n > MAX_ENUMERATION_VARIABLES:
            raise InputError(
                f"component {k} has {n} variables; enumeration handles at most "
                f"{MAX_ENUMERATION_VARIABLES}. Use belief propagation or gtsam for it."
            )
        bits, log_w = _component_log_weights(graph, k, dtype)
        local_ev = evidence[:, torch.from_numpy(variables)]  # (B, n)
        patterns, inverse = torch.unique(local_ev, dim=0, return_inverse=True)  # (U, n)
        clamped = patterns >= 0
        agree = (bits[None] == (patterns[:, None] == 1)) | ~clamped[:, None]  # (U, S, n)
        logits = torch.where(agree.all(-1), log_w[None], torch.tensor(float("-inf"), dtype=dtype))
        p = torch.softmax(logits, dim=-1)  # (U, S)
        p1 = (p @ bits.to(dtype)).clamp(0.0, 1.0)  # (U, n)
        out[:, torch.from_numpy(variables), 1] = p1[inverse]
        out[:, torch.from_numpy(variables), 0] = 1 - p1[inverse]
    return out
