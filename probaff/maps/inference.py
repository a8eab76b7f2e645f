"""Marginals of an affordance map: exact where affordable, loopy BP elsewhere.

``method="auto"`` solves components of at most `MAX_ENUMERATION_VARIABLES` variables exactly
by batched enumeration in torch, other components whose elimination width allows it with gtsam
when there is a single evidence row, and everything else with batched loopy BP.

``method="bp"`` on a map whose every cell holds a box and that has no symmetry factors (a
"full rectangle": four independent ``H x W`` Ising grids, one per direction) runs the grid
solver `grid_belief_propagation` on the four grids laid side by side, which gives the same
messages as the generic solver without any edge list.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import torch

from probaff._checks import check_count
from probaff.errors import InputError
from probaff.maps.bp import BeliefPropagationResult, loopy_belief_propagation
from probaff.maps.enumeration import MAX_ENUMERATION_VARIABLES, enumerate_marginals
from probaff.maps.evidence import as_evidence
from probaff.maps.exact import DEFAULT_MAX_EXACT_WIDTH, component_widths, exact_marginals
from probaff.maps.graph import AffordanceGraph
from probaff.maps.grid_bp import grid_belief_propagation
from probaff.maps.options import BPOptions, resolve_bp_options

__all__ = ["BP_SOLVERS", "METHODS", "MapMarginals", "affordance_marginals", "is_full_grid"]

BP_SOLVERS = ("generic", "grid")
"""Values of `MapMarginals.bp_solver` when BP ran: the edge-list or the grid solver."""

METHODS = ("auto", "bp", "exact")
"""Accepted values of ``method``."""


@dataclass(frozen=True)
class MapMarginals:
    """Marginals of a map and how each component was solved.

    Attributes:
        marginals: ``(V, 2)`` or, for batched evidence, ``(B, V, 2)`` probabilities.
        component_methods: ``"enumeration"``, ``"exact"`` (gtsam) or ``"bp"`` for each entry
            of ``graph.components``.
        bp: Diagnostics of the belief propagation run over the "bp" components, if any; its
            ``marginals`` are ``(B, n, 2)`` (or ``(n, 2)``) over the BP variables in the order
            of the concatenated BP components.
        bp_solver: ``"generic"`` (edge lists) or ``"grid"`` (`grid_belief_propagation`) when
            BP ran, else None.
    """

    marginals: torch.Tensor
    component_methods: tuple[str, ...]
    bp: BeliefPropagationResult | None
    bp_solver: str | None = None


def is_full_grid(graph: AffordanceGraph) -> bool:
    """Whether `graph` is a full rectangle: a box in every cell and no symmetry factors.

    Such a map is four independent ``H x W`` Ising grids (one per direction), with `coupling`
    across the direction and `along_coupling` along it.

    Args:
        graph: The affordance map.

    Returns:
        True when the grid solver applies.
    """
    return bool(graph.occupancy.all()) and graph.symmetry_coupling is None


def _grid_bp(graph: AffordanceGraph, ev: torch.Tensor, opts: BPOptions) -> BeliefPropagationResult:
    """BP on a full-rectangle map with the grid solver; marginals ``(B, V, 2)`` (global order).

    The four direction grids ``(H, W)`` are laid side by side as one ``(H, 4W)`` grid; the
    horizontal coupling between two blocks is 0, which removes those edges.
    """
    height, width = graph.shape
    n_dir = 4
    # Variable v = (r * W + c) * 4 + d sits at grid cell (r, d * W + c).
    unary = graph.unary_log_potentials(opts.dtype).reshape(height, width, n_dir, 2)
    unary = unary.permute(0, 2, 1, 3).reshape(height, n_dir * width, 2)
    evidence = ev.reshape(-1, height, width, n_dir).permute(0, 1, 3, 2)
    evidence = evidence.reshape(-1, height, n_dir * width)
    across, along = graph.coupling, graph.along_coupling
    vertical_j = [along, along, across, across]  # up/down lie along a column
    horizontal_j = [across, across, along, along]
    vertical = np.repeat(np.asarray(vertical_j, dtype=np.float64), width)
    vertical = np.broadcast_to(vertical, (max(height - 1, 0), n_dir * width))
    horizontal = np.zeros(n_dir * width - 1)
    for d in range(n_dir):
        horizontal[d * width : d * width + width - 1] = horizontal_j[d]
    horizontal = np.broadcast_to(horizontal, (height, n_dir * width - 1))
    result = grid_belief_propagation(
        unary, (vertical.copy(), horizontal.copy()), evidence, options=opts
    )
    marg = result.marginals.reshape(-1, height, n_dir, width, 2).permute(0, 1, 3, 2, 4)
    return BeliefPropagationResult(
        marginals=marg.reshape(-1, graph.num_variables, 2),
        converged=result.converged,
        iterations=result.iterations,
        max_delta=result.max_delta,
    )


def affordance_marginals(
    graph: AffordanceGraph,
    evidence: Any = None,
    *,
    method: str = "auto",
    max_exact_width: int = DEFAULT_MAX_EXACT_WIDTH,
    options: BPOptions | None = None,
    **overrides: Any,
) -> MapMarginals:
    """Marginal pushability of every (box, direction), optionally under evidence.

    Args:
        graph: The affordance map.
        evidence: None, ``(V,)`` or ``(B, V)`` values in {-1 (free), 0, 1}.
        method: ``"exact"`` (gtsam on every component; raises on a component whose
            min-degree elimination width exceeds `max_exact_width`), ``"bp"`` (loopy belief
            propagation everywhere) or ``"auto"`` (batched enumeration for small components;
            for larger ones gtsam where the width allows and the evidence is a single row,
            else BP; all BP components in one batched run; a full-rectangle map, see
            `is_full_grid`, runs `grid_belief_propagation` under ``"bp"``).
        max_exact_width: Width limit of exact inference (an integer >= 0).
        options: BP settings (`BPOptions`); ``options.dtype`` is also the dtype of the
            returned marginals. None for the defaults.
        **overrides: ``damping``, ``tol``, ``max_iterations`` or ``dtype``: override that
            field of `options` when given (not None).

    Returns:
        The marginals and per-component methods.

    Raises:
        InputError: On an unknown method, malformed evidence, BP options out of range, a
            count that is not an integer, or an exact request on a component that is too wide.
    """
    if method not in METHODS:
        raise InputError(f"method must be one of {METHODS}, got {method!r}.")
    max_exact_width = check_count("max_exact_width", max_exact_width, minimum=0)
    opts = resolve_bp_options(options, **overrides)
    ev, batched = as_evidence(evidence, (graph.num_variables,))
    count = len(graph.components)
    if method == "bp" and graph.num_edges and is_full_grid(graph):
        grid = _grid_bp(graph, ev, opts)
        full = grid.marginals  # (B, V, 2), global order
        order = torch.from_numpy(np.concatenate(graph.components))
        bp_order = full[:, order]  # the generic path's BP order: concatenated components
        diagnostics = BeliefPropagationResult(
            marginals=bp_order if batched else bp_order[0],
            converged=grid.converged,
            iterations=grid.iterations,
            max_delta=grid.max_delta,
        )
        return MapMarginals(full if batched else full[0], ("bp",) * count, diagnostics, "grid")
    if method == "exact":
        exact = exact_marginals(graph, ev, max_width=max_exact_width).to(opts.dtype)
        return MapMarginals(exact if batched else exact[0], ("exact",) * count, None)
    methods = _component_methods(graph, ev, method, max_exact_width)
    out, bp_result = _mixed_marginals(graph, ev, methods, max_exact_width, opts)
    return MapMarginals(
        out if batched else out[0], methods, bp_result, "generic" if bp_result is not None else None
    )


def _component_methods(
    graph: AffordanceGraph, ev: torch.Tensor, method: str, max_exact_width: int
) -> tuple[str, ...]:
    """How each component is solved under `method` (``"auto"`` or ``"bp"``).

    See `affordance_marginals`; one of ``"enumeration"``, ``"exact"`` or ``"bp"`` per entry
    of ``graph.components``.
    """
    count = len(graph.components)
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
    return tuple(
        "bp" if k in bp_set else "enumeration" if k in enum_set else "exact" for k in range(count)
    )


def _mixed_marginals(
    graph: AffordanceGraph,
    ev: torch.Tensor,
    methods: tuple[str, ...],
    max_exact_width: int,
    opts: BPOptions,
) -> tuple[torch.Tensor, BeliefPropagationResult | None]:
    """Marginals ``(B, V, 2)`` with each component solved by its method, and the BP run."""
    dtype = opts.dtype
    use_enum, use_exact, use_bp = (
        [k for k, m in enumerate(methods) if m == name] for name in ("enumeration", "exact", "bp")
    )
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
            options=opts,
        )
        out[:, var_t] = bp_result.marginals
    return out, bp_result
