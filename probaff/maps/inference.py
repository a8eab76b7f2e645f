"""Marginals of an affordance map: exact where affordable, loopy BP elsewhere.

``method="auto"`` solves components of at most `MAX_ENUMERATION_VARIABLES` variables exactly
by batched enumeration in torch, other components whose elimination width allows it with gtsam
when there is a single evidence row, and everything else with batched loopy BP.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import torch

from probaff._checks import check_count
from probaff.errors import InputError
from probaff.maps.bp import (
    DEFAULT_DAMPING,
    DEFAULT_MAX_ITERATIONS,
    DEFAULT_TOL,
    BeliefPropagationResult,
    loopy_belief_propagation,
)
from probaff.maps.enumeration import MAX_ENUMERATION_VARIABLES, enumerate_marginals
from probaff.maps.evidence import as_evidence
from probaff.maps.exact import DEFAULT_MAX_EXACT_WIDTH, component_widths, exact_marginals
from probaff.maps.graph import AffordanceGraph

__all__ = ["METHODS", "MapMarginals", "affordance_marginals"]

METHODS = ("auto", "bp", "exact")
"""Accepted values of ``method``."""


@dataclass(frozen=True)
class MapMarginals:
    """Marginals of a map and how each component was solved.

    Attributes:
        marginals: ``(V, 2)`` or, for batched evidence, ``(B, V, 2)`` probabilities.
        component_methods: ``"enumeration"``, ``"exact"`` (gtsam) or ``"bp"`` for each entry
            of ``graph.components``.
        bp: Diagnostics of the belief propagation run over the "bp" components, if any.
    """

    marginals: torch.Tensor
    component_methods: tuple[str, ...]
    bp: BeliefPropagationResult | None


def affordance_marginals(
    graph: AffordanceGraph,
    evidence: Any = None,
    *,
    method: str = "auto",
    max_exact_width: int = DEFAULT_MAX_EXACT_WIDTH,
    damping: float = DEFAULT_DAMPING,
    tol: float = DEFAULT_TOL,
    max_iterations: int = DEFAULT_MAX_ITERATIONS,
    dtype: torch.dtype = torch.float32,
) -> MapMarginals:
    """Marginal pushability of every (box, direction), optionally under evidence.

    Args:
        graph: The affordance map.
        evidence: None, ``(V,)`` or ``(B, V)`` values in {-1 (free), 0, 1}.
        method: ``"exact"`` (gtsam on every component; raises on a component whose
            min-degree elimination width exceeds `max_exact_width`), ``"bp"`` (loopy belief
            propagation everywhere) or ``"auto"`` (batched enumeration for small components;
            for larger ones gtsam where the width allows and the evidence is a single row,
            else BP; all BP components in one batched run).
        max_exact_width: Width limit of exact inference (an integer >= 0).
        damping: BP damping, see `loopy_belief_propagation`.
        tol: BP convergence tolerance.
        max_iterations: BP iteration budget (a positive integer).
        dtype: Floating dtype of BP and of the returned marginals.

    Returns:
        The marginals and per-component methods.

    Raises:
        InputError: On an unknown method, malformed evidence, a count that is not an
            integer, or an exact request on a component that is too wide.
    """
    if method not in METHODS:
        raise InputError(f"method must be one of {METHODS}, got {method!r}.")
    max_exact_width = check_count("max_exact_width", max_exact_width, minimum=0)
    max_iterations = check_count("max_iterations", max_iterations)
    ev, batched = as_evidence(evidence, (graph.num_variables,))
    count = len(graph.components)
    if method == "exact":
        exact = exact_marginals(graph, ev, max_width=max_exact_width).to(dtype)
        return MapMarginals(exact if batched else exact[0], ("exact",) * count, None)
    use_enum: list[int] = []
    if method == "bp":
        use_bp = list(range(count))
    else:
        sizes = [int(c.size) for c in graph.components]
        use_enum = [k for k in range(count) if sizes[k] <= MAX_ENUMERATION_VARIABLES]
        rest = [k for k in range(count) if sizes[k] > MAX_ENUMERATION_VARIABLES]
        if ev.shape[0] == 1:
            widths = component_widths(graph, rest, limit=max_exact_width)
            use_bp = [k for k, w in zip(rest, widths, strict=True) if w > max_exact_width]
        else:
            use_bp = rest
    bp_set, enum_set = set(use_bp), set(use_enum)
    use_exact = [k for k in range(count) if k not in bp_set and k not in enum_set]

    out = torch.empty((ev.shape[0], graph.num_variables, 2), dtype=dtype)
    if use_enum:
        enum = enumerate_marginals(graph, ev, use_enum, torch.float64)
        mask = torch.from_numpy(np.isin(graph.component_index, use_enum))
        out[:, mask] = enum[:, mask].to(dtype)
    if use_exact:
        exact = exact_marginals(graph, ev, max_width=max_exact_width, components=use_exact)
        mask = torch.from_numpy(np.isin(graph.component_index, use_exact))
        out[:, mask] = exact[:, mask].to(dtype)
    bp_result = None
    if use_bp:
        variables = np.concatenate([graph.components[k] for k in use_bp])
        edge_ids = np.concatenate([graph.component_edge_ids[k] for k in use_bp])
        local = np.full(graph.num_variables, -1, dtype=np.int64)
        local[variables] = np.arange(variables.size)
        var_t = torch.from_numpy(variables)
        bp_result = loopy_belief_propagation(
            graph.unary_log_potentials(dtype)[var_t],
            torch.from_numpy(local[graph.edges[edge_ids]]),
            graph.pairwise_log_potentials(dtype)[torch.from_numpy(edge_ids)],
            ev[:, var_t],
            damping=damping,
            tol=tol,
            max_iterations=max_iterations,
            dtype=dtype,
        )
        out[:, var_t] = bp_result.marginals
    methods = tuple("bp" if k in bp_set else "enumeration" if k in enum_set else "exact"
                    for k in range(count))
    return MapMarginals(out if batched else out[0], methods, bp_result)
