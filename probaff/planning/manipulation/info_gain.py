"""Information-gain push planning on an affordance map (chapter 3).

A candidate push is a (believed box cell, direction) pair whose *access cell*, the cell on the far
side of the box from the push (``cell - offset``), lies inside the map and has a travel distance:
the caller passes an ``(H, W)`` array of path lengths from the robot to every cell it may push
from (-1 elsewhere), e.g. `probaff.planning.manipulation.loop.travel_distances`, so that this
module needs no perception. Its cost ``C`` is that distance in cells. Its reward is the
expected drop of the whole-map entropy once the affordance is confirmed,

    R = H(map) - [p H(map | x = 1) + (1 - p) H(map | x = 0)],

with ``H`` the sum of the marginal entropies (nats) of every variable of the MRF and ``p`` the
variable's current marginal ``P(x = 1)``. The score is ``G = alpha R - (1 - alpha) C``.

Every conditioned map is solved in one batched `affordance_marginals` call: one evidence row for
the map as it stands, then two per candidate (its variable clamped to 1, then to 0) on top of
the evidence already confirmed. Variables already confirmed are not candidates.

Covered by tests/planning/manipulation/test_info_gain.py.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import torch

from probaff._checks import as_real_array
from probaff.errors import InputError
from probaff.grid import DIRECTION_OFFSETS
from probaff.maps.entropy import map_entropy
from probaff.maps.evidence import FREE, as_evidence
from probaff.maps.graph import AffordanceGraph
from probaff.maps.inference import affordance_marginals
from probaff.maps.options import DEFAULT_ALPHA, BPOptions, check_alpha

__all__ = [
    "PushCandidate",
    "PushCandidates",
    "PushPlan",
    "candidate_pushes",
    "check_graph",
    "expected_entropies",
    "plan_pushes",
]


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


def _check_distances(distances: Any, shape: tuple[int, int]) -> np.ndarray:
    """``(H, W)`` int64 travel distances, or `InputError`."""
    dist = as_real_array("distances", distances)
    if dist.shape != shape:
        raise InputError(f"distances has shape {dist.shape}, expected the map's {shape}.")
    if not np.issubdtype(dist.dtype, np.integer):
        raise InputError(
            f"distances must hold integer path lengths (cells; -1 where the robot cannot "
            f"push from), got dtype {dist.dtype}."
        )
    return dist.astype(np.int64, copy=False)


def check_graph(graph: Any) -> AffordanceGraph:
    """`graph`, or `InputError` unless it is an `AffordanceGraph`."""
    if not isinstance(graph, AffordanceGraph):
        raise InputError(
            "graph must be an AffordanceGraph (AffordanceGraph(occupancy, unary, ...)), got "
            f"{type(graph).__name__}."
        )
    return graph


def candidate_pushes(
    graph: AffordanceGraph, distances: Any, evidence: Any = None
) -> PushCandidates:
    """Every untested (box, direction) whose access cell the robot can reach.

    Args:
        graph: The affordance map over the believed boxes.
        distances: ``(H, W)`` int path length (cells) from the robot to each cell it may push
            from; negative where it cannot (unreachable or not believed free).
        evidence: None or (V,) values in {-1, 0, 1}; clamped variables are not candidates.

    Returns:
        The candidates, ordered by variable index (row-major cells, direction fastest).

    Raises:
        InputError: For a `graph` that is not an `AffordanceGraph`, mismatched or non-integer
            `distances`, or bad evidence.
    """
    dist = _check_distances(distances, check_graph(graph).shape)
    ev, _ = as_evidence(evidence, (graph.num_variables,))
    if ev.shape[0] != 1:
        raise InputError("candidate_pushes takes one evidence row (V,), not a batch.")
    cells = graph.variable_cells
    dirs = graph.variable_directions
    access = cells - DIRECTION_OFFSETS[dirs]
    h, w = graph.shape
    inside = (access[:, 0] >= 0) & (access[:, 0] < h) & (access[:, 1] >= 0) & (access[:, 1] < w)
    ok = inside & (ev[0].numpy() == FREE)
    a = np.where(inside[:, None], access, 0)
    cost = dist[a[:, 0], a[:, 1]]
    ok &= cost >= 0
    keep = np.flatnonzero(ok)
    return PushCandidates(
        variables=keep.astype(np.int64),
        cells=cells[keep].astype(np.int64),
        directions=dirs[keep].astype(np.int64),
        access=access[keep].astype(np.int64),
        costs=cost[keep].astype(np.int64),
    )


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


def expected_entropies(
    graph: AffordanceGraph,
    evidence: torch.Tensor,
    variables: np.ndarray,
    method: str = "auto",
    options: BPOptions | None = None,
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
    """Entropies of the map now and with each variable clamped, in one batched inference.

    Args:
        graph: The affordance map.
        evidence: (V,) int8 evidence already confirmed.
        variables: (n,) candidate variables (not clamped in `evidence`).
        method: Inference method of `affordance_marginals`.
        options: BP settings; None for `BPOptions` with float64 (entropies are differences
            of nearly equal sums, so they are computed in double precision).

    Returns:
        ``(marginals (V, 2), H (), H1 (n,), H0 (n,))``: the current marginals and map entropy,
        and the map entropy with each candidate clamped to 1 and to 0 (float64, nats).
    """
    check_graph(graph)
    n = int(variables.size)
    rows = evidence.reshape(1, -1).repeat(1 + 2 * n, 1)
    idx = torch.as_tensor(variables, dtype=torch.int64)
    k = torch.arange(n)
    rows[1 + 2 * k, idx] = 1
    rows[2 + 2 * k, idx] = 0
    opts = BPOptions(dtype=torch.float64) if options is None else options
    marg = affordance_marginals(graph, rows, method=method, options=opts).marginals
    h = map_entropy(marg)
    return marg[0], h[0], h[1::2], h[2::2]


def plan_pushes(
    graph: AffordanceGraph,
    distances: Any,
    evidence: Any = None,
    alpha: float = DEFAULT_ALPHA,
    method: str = "auto",
    options: BPOptions | None = None,
) -> PushPlan:
    """Score every candidate push by its information gain.

    Args:
        graph: The affordance map over the believed boxes.
        distances: ``(H, W)`` int path length (cells) from the robot to each cell it may push
            from; negative where it cannot (see `candidate_pushes`).
        evidence: None or (V,) values in {-1, 0, 1}: the affordances confirmed so far.
        alpha: Weight of the reward, in [0, 1].
        method: Inference method of `affordance_marginals` ("auto": exact enumeration for small
            components, batched loopy BP for large ones).
        options: BP settings of `expected_entropies`; None for the float64 defaults.

    Returns:
        The candidates sorted by ``G`` (largest first), with the current entropy and marginals.

    Raises:
        InputError: For ``alpha`` outside [0, 1], a `graph` that is not an `AffordanceGraph`
            or malformed inputs.
    """
    a = check_alpha(alpha)
    cand = candidate_pushes(graph, distances, evidence)
    ev = as_evidence(evidence, (graph.num_variables,))[0][0]
    marg, h, h1, h0 = expected_entropies(graph, ev, cand.variables, method, options)
    p = marg[torch.as_tensor(cand.variables, dtype=torch.int64), 1]
    # A branch of probability 0 contributes nothing, even if its conditioned map is undefined.
    expected = torch.where(p > 0, p * h1, torch.zeros_like(h1)) + torch.where(
        p < 1, (1 - p) * h0, torch.zeros_like(h0)
    )
    reward = (h - expected).numpy()
    gain = a * reward - (1.0 - a) * cand.costs
    order = np.argsort(-gain, kind="stable")
    out = tuple(
        PushCandidate(
            cell=(int(cand.cells[i, 0]), int(cand.cells[i, 1])),
            direction=int(cand.directions[i]),
            access=(int(cand.access[i, 0]), int(cand.access[i, 1])),
            variable=int(cand.variables[i]),
            p=float(p[i]),
            reward=float(reward[i]),
            cost=int(cand.costs[i]),
            gain=float(gain[i]),
        )
        for i in order
    )
    return PushPlan(candidates=out, entropy=float(h), marginals=marg, alpha=a)
