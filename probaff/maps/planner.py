"""Information-gain push planning on an affordance map (chapter 3).

A candidate push is a (believed box cell, direction) pair whose *access cell*, the cell on the far
side of the box from the push (``cell - offset``), lies inside the map, is believed free and is
reachable from the robot through believed-free cells (4-connected). Its cost ``C`` is the length
of that path in cells. Its reward is the expected drop of the whole-map entropy once the
affordance is confirmed,

    R = H(map) - [p H(map | x = 1) + (1 - p) H(map | x = 0)],

with ``H`` the sum of the marginal entropies (nats) of every variable of the MRF and ``p`` the
variable's current marginal ``P(x = 1)``. The score is ``G = alpha R - (1 - alpha) C``.

Every conditioned map is solved in one batched `affordance_marginals` call: one evidence row for
the map as it stands, then two per candidate (its variable clamped to 1, then to 0) on top of
the evidence already confirmed. Variables already confirmed are not candidates.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import torch

from probaff.errors import InputError
from probaff.grid import DIRECTION_OFFSETS
from probaff.maps.entropy import map_entropy
from probaff.maps.evidence import FREE, as_evidence
from probaff.maps.graph import AffordanceGraph
from probaff.maps.inference import affordance_marginals
from probaff.perception.exploration import grid_distances

__all__ = [
    "DEFAULT_ALPHA",
    "PushCandidate",
    "PushCandidates",
    "PushPlan",
    "candidate_pushes",
    "check_alpha",
    "expected_entropies",
    "plan_pushes",
]

DEFAULT_ALPHA = 0.8
"""Weight ``alpha`` of the reward against the travel cost in ``G = alpha R - (1 - alpha) C``."""


def check_alpha(alpha: float) -> float:
    """Return `alpha` as a float, or raise `InputError` unless it is a number in [0, 1].

    Args:
        alpha: Weight of the reward in the information gain.
    """
    try:
        a = float(alpha)
    except (TypeError, ValueError):
        raise InputError(f"alpha must be a number in [0, 1], got {alpha!r}.") from None
    if not (math.isfinite(a) and 0.0 <= a <= 1.0):
        raise InputError(
            f"alpha must lie in [0, 1] (1 weighs only the entropy reduction, 0 only the travel "
            f"cost), got {alpha!r}."
        )
    return a


@dataclass(frozen=True)
class PushCandidates:
    """The pushes the robot can make now.

    Attributes:
        variables: (n,) int64 variable of each candidate in the graph.
        cells: (n, 2) int64 ``(row, col)`` of the box.
        directions: (n,) int64 push direction (index into `DIRECTION_NAMES`).
        access: (n, 2) int64 ``(row, col)`` of the access cell the robot pushes from.
        costs: (n,) int64 path length (cells) from the robot to the access cell.
    """

    variables: np.ndarray
    cells: np.ndarray
    directions: np.ndarray
    access: np.ndarray
    costs: np.ndarray

    def __len__(self) -> int:
        return int(self.variables.size)


def _check_robot(robot: Any, shape: tuple[int, int]) -> tuple[int, int]:
    cell = np.asarray(robot)
    if cell.shape != (2,) or not np.issubdtype(cell.dtype, np.integer):
        raise InputError(f"robot must be an integer (row, col) cell, got {robot!r}.")
    r, c = int(cell[0]), int(cell[1])
    if not (0 <= r < shape[0] and 0 <= c < shape[1]):
        raise InputError(f"robot cell ({r}, {c}) lies outside the {shape[0]} x {shape[1]} map.")
    return r, c


def candidate_pushes(graph: AffordanceGraph, passable: np.ndarray, robot: Any,
                     evidence: Any = None) -> PushCandidates:
    """Every untested (box, direction) whose access cell the robot can reach.

    Args:
        graph: The affordance map over the believed boxes.
        passable: (H, W) bool, the cells believed free (the robot drives only through these).
        robot: ``(row, col)`` of the robot's cell.
        evidence: None or (V,) values in {-1, 0, 1}; clamped variables are not candidates.

    Returns:
        The candidates, ordered by variable index (row-major cells, direction fastest).

    Raises:
        InputError: For a mismatched `passable`, a robot outside the map, or bad evidence.
    """
    free = np.asarray(passable, dtype=bool)
    if free.shape != graph.shape:
        raise InputError(f"passable has shape {free.shape}, expected the map's {graph.shape}.")
    here = _check_robot(robot, graph.shape)
    ev, _ = as_evidence(evidence, (graph.num_variables,))
    if ev.shape[0] != 1:
        raise InputError("candidate_pushes takes one evidence row (V,), not a batch.")
    dist = grid_distances(free, here)
    cells = graph.variable_cells
    dirs = graph.variable_directions
    access = cells - DIRECTION_OFFSETS[dirs]
    h, w = graph.shape
    inside = ((access[:, 0] >= 0) & (access[:, 0] < h) & (access[:, 1] >= 0)
              & (access[:, 1] < w))
    ok = inside & (ev[0].numpy() == FREE)
    a = np.where(inside[:, None], access, 0)
    cost = dist[a[:, 0], a[:, 1]]
    ok &= (cost >= 0) & free[a[:, 0], a[:, 1]]
    keep = np.flatnonzero(ok)
    return PushCandidates(variables=keep.astype(np.int64), cells=cells[keep].astype(np.int64),
                          directions=dirs[keep].astype(np.int64),
                          access=access[keep].astype(np.int64),
                          costs=cost[keep].astype(np.int64))


@dataclass(frozen=True)
class PushCandidate:
    """One scored push.

    Attributes:
        cell: ``(row, col)`` of the box.
        direction: Push direction (index into `DIRECTION_NAMES`).
        access: ``(row, col)`` of the cell the robot pushes from.
        variable: The variable confirmed by the push.
        p: Current marginal ``P(x = 1)`` of that variable.
        reward: ``R``, the expected whole-map entropy reduction (nats).
        cost: ``C``, the path length to the access cell (cells).
        gain: ``G = alpha R - (1 - alpha) C``.
    """

    cell: tuple[int, int]
    direction: int
    access: tuple[int, int]
    variable: int
    p: float
    reward: float
    cost: int
    gain: float


@dataclass(frozen=True)
class PushPlan:
    """The scored candidates of one planning step.

    Attributes:
        candidates: Every candidate, best ``G`` first (ties keep variable order).
        entropy: ``H(map)`` under the current evidence (nats).
        marginals: (V, 2) current marginals.
        alpha: The weight used.
    """

    candidates: tuple[PushCandidate, ...]
    entropy: float
    marginals: torch.Tensor
    alpha: float

    @property
    def best(self) -> PushCandidate | None:
        """The candidate with the largest ``G``; None if there is none."""
        return self.candidates[0] if self.candidates else None

    @property
    def worthwhile(self) -> bool:
        """Whether some candidate has ``G >= 0``; the loop stops otherwise."""
        return bool(self.candidates) and self.candidates[0].gain >= 0.0


def expected_entropies(graph: AffordanceGraph, evidence: torch.Tensor,
                       variables: np.ndarray, method: str = "auto"
                       ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
    """Entropies of the map now and with each variable clamped, in one batched inference.

    Args:
        graph: The affordance map.
        evidence: (V,) int8 evidence already confirmed.
        variables: (n,) candidate variables (not clamped in `evidence`).
        method: Inference method of `affordance_marginals`.

    Returns:
        ``(marginals (V, 2), H (), H1 (n,), H0 (n,))``: the current marginals and map entropy,
        and the map entropy with each candidate clamped to 1 and to 0 (float64, nats).
    """
    n = int(variables.size)
    rows = evidence.reshape(1, -1).repeat(1 + 2 * n, 1)
    idx = torch.as_tensor(variables, dtype=torch.int64)
    k = torch.arange(n)
    rows[1 + 2 * k, idx] = 1
    rows[2 + 2 * k, idx] = 0
    marg = affordance_marginals(graph, rows, method=method, dtype=torch.float64).marginals
    h = map_entropy(marg)
    return marg[0], h[0], h[1::2], h[2::2]


def plan_pushes(graph: AffordanceGraph, passable: np.ndarray, robot: Any, evidence: Any = None,
                alpha: float = DEFAULT_ALPHA, method: str = "auto") -> PushPlan:
    """Score every candidate push by its information gain.

    Args:
        graph: The affordance map over the believed boxes.
        passable: (H, W) bool, the cells believed free.
        robot: ``(row, col)`` of the robot's cell.
        evidence: None or (V,) values in {-1, 0, 1}: the affordances confirmed so far.
        alpha: Weight of the reward, in [0, 1].
        method: Inference method of `affordance_marginals` ("auto": exact enumeration for small
            components, batched loopy BP for large ones).

    Returns:
        The candidates sorted by ``G`` (largest first), with the current entropy and marginals.

    Raises:
        InputError: For ``alpha`` outside [0, 1] or malformed inputs.
    """
    a = check_alpha(alpha)
    cand = candidate_pushes(graph, passable, robot, evidence)
    ev = as_evidence(evidence, (graph.num_variables,))[0][0]
    marg, h, h1, h0 = expected_entropies(graph, ev, cand.variables, method)
    p = marg[torch.as_tensor(cand.variables, dtype=torch.int64), 1]
    # A branch of probability 0 contributes nothing, even if its conditioned map is undefined.
    expected = (torch.where(p > 0, p * h1, torch.zeros_like(h1))
                + torch.where(p < 1, (1 - p) * h0, torch.zeros_like(h0)))
    reward = (h - expected).numpy()
    gain = a * reward - (1.0 - a) * cand.costs
    order = np.argsort(-gain, kind="stable")
    out = tuple(
        PushCandidate(cell=(int(cand.cells[i, 0]), int(cand.cells[i, 1])),
                      direction=int(cand.directions[i]),
                      access=(int(cand.access[i, 0]), int(cand.access[i, 1])),
                      variable=int(cand.variables[i]), p=float(p[i]), reward=float(reward[i]),
                      cost=int(cand.costs[i]), gain=float(gain[i]))
        for i in order)
    return PushPlan(candidates=out, entropy=float(h), marginals=marg, alpha=a)
