"""The affordance MRF of a warehouse grid map, as a gtsam factor graph and as tensors.

Every occupied cell (a box) carries four binary variables, "pushable up / down / left /
right", ordered as in `DIRECTIONS`. Rows are indexed top to bottom, so "up" moves to a
*smaller* row index and "left" to a smaller column index. With ``s = 2x - 1`` the joint is

    P(x) ∝ Π_i φ_i(x_i) Π_(i,j) ψ_ij(x_i, x_j),

* unary ``φ_i = (1 - p_i, p_i)`` with ``p_i`` the classifier's ``p(x_i = 1)``;
* Ising ``ψ_ij = exp(J s_i s_j)`` between the *same* direction of two 4-neighbouring
  occupied cells;
* optional symmetry factors ``exp(J_sym s_a s_b)`` between "pushable up" of a cell and
  "pushable down" of the cell directly above it (row - 1), and between "pushable left" of a
  cell and "pushable right" of the cell directly left of it (column - 1). As a table with
  rows ``x_a`` (the lower / right cell's variable) and columns ``x_b`` (the upper / left
  cell's variable)::

                  x_b = 0       x_b = 1
        x_a = 0   exp(J_sym)    exp(-J_sym)
        x_a = 1   exp(-J_sym)   exp(J_sym)

  so ``J_sym > 0`` favours agreement: if a box cannot be pushed up into the box above it,
  that box tends not to be pushable down into it either.

Variables are numbered row-major over occupied cells, direction fastest.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from functools import cached_property
from typing import Any

import gtsam
import numpy as np
import torch

from probaff._checks import (
    as_bool_array,
    as_float_array,
    as_real_tensor,
    check_finite,
    check_probability,
    check_shape,
)
from probaff.errors import InputError
from probaff.grid import DIRECTION_NAMES
from probaff.maps.components import component_labels, group_components
from probaff.maps.options import DEFAULT_COUPLING, MAX_COUPLING, check_coupling

__all__ = [
    "DEFAULT_COUPLING",
    "DIRECTIONS",
    "EDGE_ISING",
    "EDGE_SYMMETRY",
    "MAX_COUPLING",
    "AffordanceGraph",
    "check_coupling",
]

DIRECTIONS: tuple[str, ...] = DIRECTION_NAMES
"""Direction order of the last axis of unary arrays; "up" decreases the row index."""

EDGE_ISING = 0
"""`AffordanceGraph.edge_kinds` value of a same-direction Ising edge."""

EDGE_SYMMETRY = 1
"""`AffordanceGraph.edge_kinds` value of an up/down or left/right symmetry edge."""

_UP, _DOWN, _LEFT, _RIGHT = range(4)


def _check_occupancy(occupancy: Any) -> np.ndarray:
    occ = as_bool_array("occupancy", occupancy)
    if occ.ndim != 2:
        raise InputError(f"occupancy must be a 2-D (H, W) grid, got shape {occ.shape}.")
    return occ


class AffordanceGraph:
    """Pushability MRF of one grid map.

    Array attributes are shared, not copied, by every accessor: treat them as read-only.

    Attributes:
        occupancy: ``(H, W)`` bool, True where a box stands.
        unary: ``(H, W, 4)`` float64 classifier probabilities ``p(x = 1)``, directions in
            `DIRECTIONS` order; entries of free cells are ignored.
        coupling: Ising strength ``J``.
        symmetry_coupling: Symmetry strength ``J_sym``, or None when those factors are absent.
        variable_index: ``(H, W, 4)`` int64 variable of each (cell, direction); -1 if free.
        variable_cells: ``(V, 2)`` int64 (row, column) of each variable.
        variable_directions: ``(V,)`` int64 direction (index into `DIRECTIONS`).
        probabilities: ``(V,)`` float64 unary ``p(x_v = 1)``.
        edges: ``(E, 2)`` int64 variable pairs ``(a, b)`` with ``a < b``.
        edge_kinds: ``(E,)`` int8, `EDGE_ISING` or `EDGE_SYMMETRY`.
        edge_couplings: ``(E,)`` float64 strength of each edge.
    """

    def __init__(
        self,
        occupancy: Any,
        unary: Any,
        coupling: float = DEFAULT_COUPLING,
        symmetry_coupling: float | None = None,
        along_coupling: float | None = None,
    ) -> None:
        """Build the graph.

        Args:
            occupancy: ``(H, W)`` boolean grid (0/1 accepted).
            unary: ``(H, W, 4)`` probabilities ``p(pushable)`` per cell and direction (up,
                down, left, right). Values of free cells are ignored, but NaN or infinite
                values anywhere are rejected.
            coupling: Ising strength ``J`` with ``|J| <= MAX_COUPLING``.
            symmetry_coupling: ``J_sym`` of the up/down and left/right symmetry factors
                (same range), or None to leave them out.
            along_coupling: Ising strength between neighbours that lie along the direction
                itself ("pushable up" of a box and of the box above it); None uses `coupling`
                for every pair, as in the thesis. Along a direction neighbours tend to differ
                (the lower box can never be pushed up into the upper one), so 0 or a negative
                value models that better.

        Raises:
            InputError: On a malformed grid, mismatched shapes, NaN/inf, probabilities of
                occupied cells outside [0, 1], or couplings out of range.
        """
        occ = _check_occupancy(occupancy)
        probs = as_float_array("unary", unary)
        check_shape("unary", probs, (occ.shape[0], occ.shape[1], len(DIRECTIONS)))
        check_finite("unary", probs)
        check_probability("unary (occupied cells)", probs[occ])
        self.coupling = check_coupling("coupling", coupling)
        self.symmetry_coupling = (
            None
            if symmetry_coupling is None
            else check_coupling("symmetry_coupling", symmetry_coupling)
        )
        self.along_coupling = (
            self.coupling
            if along_coupling is None
            else check_coupling("along_coupling", along_coupling)
        )
        self.occupancy = occ.copy()
        self.unary = probs.copy()

        height, width = occ.shape
        cells = np.argwhere(occ).astype(np.int64)  # row-major
        num_cells = cells.shape[0]
        index = np.full((height, width, len(DIRECTIONS)), -1, dtype=np.int64)
        index[occ] = np.arange(num_cells * len(DIRECTIONS), dtype=np.int64).reshape(-1, 4)
        self.variable_index = index
        self.variable_cells = np.repeat(cells, len(DIRECTIONS), axis=0)
        self.variable_directions = np.tile(np.arange(len(DIRECTIONS), dtype=np.int64), num_cells)
        self.probabilities = probs[occ].reshape(-1).copy()

        both_v = occ[:-1, :] & occ[1:, :]  # cell and the cell below it
        both_h = occ[:, :-1] & occ[:, 1:]  # cell and the cell right of it
        upper, lower = index[:-1, :][both_v], index[1:, :][both_v]  # (n, 4) each
        left, right = index[:, :-1][both_h], index[:, 1:][both_h]
        pairs = [
            np.stack([upper.reshape(-1), lower.reshape(-1)], axis=1),
            np.stack([left.reshape(-1), right.reshape(-1)], axis=1),
        ]
        kinds = [np.full(sum(p.shape[0] for p in pairs), EDGE_ISING, dtype=np.int8)]
        vertical_along = np.array([True, True, False, False])  # up/down lie along a column
        per_dir = np.where(vertical_along, self.along_coupling, self.coupling)
        per_dir_h = np.where(~vertical_along, self.along_coupling, self.coupling)
        couplings = [
            np.concatenate([np.tile(per_dir, upper.shape[0]), np.tile(per_dir_h, left.shape[0])])
        ]
        if self.symmetry_coupling is not None:
            sym = np.concatenate(
                [
                    np.stack([upper[:, _DOWN], lower[:, _UP]], axis=1),
                    np.stack([left[:, _RIGHT], right[:, _LEFT]], axis=1),
                ]
            )
            pairs.append(sym)
            kinds.append(np.full(sym.shape[0], EDGE_SYMMETRY, dtype=np.int8))
            couplings.append(np.full(sym.shape[0], self.symmetry_coupling))
        edges = np.sort(np.concatenate(pairs).reshape(-1, 2), axis=1)
        order = np.lexsort((edges[:, 1], edges[:, 0]))
        self.edges = np.ascontiguousarray(edges[order])
        self.edge_kinds = np.concatenate(kinds)[order]
        self.edge_couplings = np.concatenate(couplings)[order].astype(np.float64)

    @property
    def shape(self) -> tuple[int, int]:
        """Grid size ``(H, W)``."""
        return (int(self.occupancy.shape[0]), int(self.occupancy.shape[1]))

    @property
    def num_variables(self) -> int:
        """Number of binary variables ``V`` (4 per box)."""
        return int(self.probabilities.shape[0])

    @property
    def num_edges(self) -> int:
        """Number of pairwise factors ``E``."""
        return int(self.edges.shape[0])

    def variable(self, row: int, col: int, direction: int | str) -> int:
        """Index of the variable "cell (row, col) is pushable towards `direction`".

        Args:
            row: Row of the cell (0 is the top row).
            col: Column of the cell.
            direction: Index into `DIRECTIONS` or its name.

        Returns:
            The variable index in ``[0, V)``.

        Raises:
            InputError: If the cell is outside the grid or free, or the direction unknown.
        """
        if isinstance(direction, str):
            if direction not in DIRECTIONS:
                raise InputError(f"direction must be one of {DIRECTIONS}, got {direction!r}.")
            d = DIRECTIONS.index(direction)
        else:
            d = int(direction)
            if not 0 <= d < len(DIRECTIONS):
                raise InputError(f"direction index must be in [0, 3], got {direction!r}.")
        height, width = self.shape
        if not (0 <= row < height and 0 <= col < width):
            raise InputError(f"cell ({row}, {col}) lies outside the {height}x{width} grid.")
        v = int(self.variable_index[row, col, d])
        if v < 0:
            raise InputError(f"cell ({row}, {col}) is free; only occupied cells have variables.")
        return v

    def unary_log_potentials(self, dtype: torch.dtype = torch.float32) -> torch.Tensor:
        """Log unary tables ``log φ_v = (log(1 - p_v), log p_v)``.

        Args:
            dtype: Floating dtype of the result.

        Returns:
            ``(V, 2)`` tensor; ``-inf`` where a probability is exactly 0 or 1.
        """
        p = torch.tensor(self.probabilities, dtype=torch.float64)
        return torch.stack([torch.log1p(-p), torch.log(p)], dim=-1).to(dtype)

    def pairwise_log_potentials(self, dtype: torch.dtype = torch.float32) -> torch.Tensor:
        """Log pairwise tables ``log ψ_e[x_a, x_b] = J_e s_a s_b`` with ``s = 2x - 1``.

        Args:
            dtype: Floating dtype of the result.

        Returns:
            ``(E, 2, 2)`` tensor indexed ``[edge, x_a, x_b]`` for ``edges[e] = (a, b)``.
        """
        signs = torch.tensor([[1.0, -1.0], [-1.0, 1.0]], dtype=torch.float64)
        coupling = torch.tensor(self.edge_couplings, dtype=torch.float64)
        return (coupling[:, None, None] * signs).to(dtype)

    def edge_tensor(self) -> torch.Tensor:
        """Edges as a ``(E, 2)`` int64 tensor (same content as `edges`)."""
        return torch.tensor(self.edges, dtype=torch.int64)

    @cached_property
    def component_labels(self) -> np.ndarray:
        """``(V,)`` int64 component label of each variable (its component's smallest index)."""
        return component_labels(self.num_variables, self.edges)

    @cached_property
    def components(self) -> tuple[np.ndarray, ...]:
        """Variable indices of each connected component, sorted, ordered by smallest member."""
        return tuple(group_components(self.component_labels))

    @cached_property
    def component_index(self) -> np.ndarray:
        """``(V,)`` int64 position in `components` of each variable's component."""
        labels = self.component_labels
        return np.searchsorted(np.unique(labels), labels).astype(np.int64)

    @cached_property
    def component_edge_ids(self) -> tuple[np.ndarray, ...]:
        """Indices into `edges` of the edges inside each component, parallel to `components`."""
        owner = self.component_index[self.edges[:, 0]]
        order = np.argsort(owner, kind="stable")
        counts = np.bincount(owner, minlength=len(self.components))
        return tuple(np.split(order, np.cumsum(counts)[:-1]))

    def to_gtsam(
        self,
        component: int | None = None,
        evidence: Mapping[int, int] | None = None,
    ) -> gtsam.DiscreteFactorGraph:
        """Build the gtsam discrete factor graph (variable index = gtsam key, cardinality 2).

        Args:
            component: Index into `components` to build that component alone; None for the
                whole map.
            evidence: ``{variable: value}`` with value 0 or 1; a clamped variable's unary
                factor is replaced by the indicator ``(1, 0)`` or ``(0, 1)``. Entries for
                variables outside the requested component are ignored.

        Returns:
            A factor graph with one unary factor per variable and one table per edge.

        Raises:
            InputError: On an unknown component or malformed evidence.
        """
        if component is None:
            variables = np.arange(self.num_variables, dtype=np.int64)
            edge_ids = np.arange(self.num_edges, dtype=np.int64)
        else:
            if not 0 <= int(component) < len(self.components):
                raise InputError(
                    f"component {component} does not exist; the map has "
                    f"{len(self.components)} components."
                )
            variables = self.components[int(component)]
            edge_ids = self.component_edge_ids[int(component)]
        clamp = dict(evidence or {})
        for v, value in clamp.items():
            if not 0 <= int(v) < self.num_variables:
                raise InputError(
                    f"evidence names variable {v}, but the map has {self.num_variables} "
                    f"variables (indices 0..{self.num_variables - 1})."
                )
            if value not in (0, 1):
                raise InputError(f"evidence value of variable {v} must be 0 or 1, got {value!r}.")
        graph = gtsam.DiscreteFactorGraph()
        for v in variables.tolist():
            if v in clamp:
                table = [0.0, 1.0] if clamp[v] == 1 else [1.0, 0.0]
            else:
                p = float(self.probabilities[v])
                table = [1.0 - p, p]
            graph.add((v, 2), table)
        for e in edge_ids.tolist():
            a, b = (int(x) for x in self.edges[e])
            same, diff = math.exp(self.edge_couplings[e]), math.exp(-self.edge_couplings[e])
            # gtsam tables are row-major with the first key slowest: [ab=00, 01, 10, 11].
            graph.add([(a, 2), (b, 2)], [same, diff, diff, same])
        return graph

    def to_map(self, values: torch.Tensor) -> torch.Tensor:
        """Scatter per-variable values back onto the grid.

        Args:
            values: ``(..., V)`` values, e.g. ``marginals[..., 1]``.

        Returns:
            ``(..., H, W, 4)`` tensor holding NaN at free cells.
        """
        values = as_real_tensor("values", values)
        check_shape("values", values, (*(None,) * (values.dim() - 1), self.num_variables))
        if not values.is_floating_point():
            values = values.double()
        height, width = self.shape
        out = values.new_full((*values.shape[:-1], height * width * 4), float("nan"))
        flat = torch.as_tensor(np.flatnonzero(self.variable_index.reshape(-1) >= 0))
        out[..., flat] = values
        return out.reshape(*values.shape[:-1], height, width, 4)
