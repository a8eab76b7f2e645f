"""Information-gain push planning: scores against a per-candidate reference, reachability, alpha.

The planner (`probaff.planning.manipulation.info_gain`) takes travel distances;
`travel_distances` and `plan_pushes_on_grid` compute them from a drivable grid and the robot's
cell.
"""

import math

import numpy as np
import pytest
import torch

from probaff.errors import InputError
from probaff.grid import DIRECTION_OFFSETS
from probaff.maps.entropy import map_entropy
from probaff.maps.graph import AffordanceGraph
from probaff.maps.inference import affordance_marginals
from probaff.maps.options import check_alpha
from probaff.perception.exploration import grid_distances
from probaff.planning.manipulation.info_gain import candidate_pushes, plan_pushes
from probaff.planning.manipulation.loop import plan_pushes_on_grid, travel_distances

# 6 x 6 map: an L of three boxes, a pair, a lone box; column 4 of rows 0-2 is walled off by
# boxes so that the top-right corner cannot be reached from the robot at (5, 0).
OCC = np.zeros((6, 6), dtype=bool)
for cell in [(1, 1), (2, 1), (2, 2), (4, 3), (4, 4), (0, 4), (1, 4), (2, 4), (2, 5)]:
    OCC[cell] = True
ROBOT = (5, 0)


def _graph(seed: int = 0, coupling: float = 0.4, symmetry: float | None = 0.3):
    unary = np.random.default_rng(seed).uniform(0.05, 0.95, (6, 6, 4))
    return AffordanceGraph(OCC, unary, coupling, symmetry)


def _brute_force(graph, passable, robot, evidence, alpha):
    """Every candidate scored with its own inference calls, straight from the definitions."""
    base = torch.as_tensor(evidence, dtype=torch.int8)
    marg = affordance_marginals(graph, base, method="exact", dtype=torch.float64).marginals
    h = float(map_entropy(marg))
    dist = grid_distances(passable, robot)
    out = {}
    for v in range(graph.num_variables):
        if evidence[v] >= 0:
            continue
        (r, c), d = graph.variable_cells[v], graph.variable_directions[v]
        ar, ac = r - DIRECTION_OFFSETS[d][0], c - DIRECTION_OFFSETS[d][1]
        if not (0 <= ar < 6 and 0 <= ac < 6) or not passable[ar, ac] or dist[ar, ac] < 0:
            continue
        p = float(marg[v, 1])
        hs = []
        for value in (1, 0):
            ev = base.clone()
            ev[v] = value
            m = affordance_marginals(graph, ev, method="exact", dtype=torch.float64).marginals
            hs.append(float(map_entropy(m)))
        reward = h - (p * hs[0] + (1 - p) * hs[1])
        out[v] = (p, reward, int(dist[ar, ac]), alpha * reward - (1 - alpha) * dist[ar, ac])
    return h, out


@pytest.mark.parametrize("symmetry", [None, 0.3])
def test_scores_match_brute_force(symmetry):
    graph = _graph(1, symmetry=symmetry)
    passable = ~OCC
    evidence = np.full(graph.num_variables, -1, dtype=np.int8)
    evidence[graph.variable(2, 2, "up")] = 0
    evidence[graph.variable(4, 4, "left")] = 1
    plan = plan_pushes(graph, travel_distances(passable, ROBOT), evidence, alpha=0.8)
    h, ref = _brute_force(graph, passable, ROBOT, evidence, 0.8)
    assert plan.entropy == pytest.approx(h, abs=1e-9)
    assert {c.variable for c in plan.candidates} == set(ref)
    for cand in plan.candidates:
        p, reward, cost, gain = ref[cand.variable]
        assert cand.p == pytest.approx(p, abs=1e-9)
        assert cand.reward == pytest.approx(reward, abs=1e-9)
        assert cand.cost == cost and cand.gain == pytest.approx(gain, abs=1e-9)
        assert cand.reward >= -1e-12  # conditioning cannot raise marginal entropy on average
    gains = [c.gain for c in plan.candidates]
    assert gains == sorted(gains, reverse=True)
    assert plan.best is plan.candidates[0] and plan.worthwhile == (gains[0] >= 0)


def test_unreachable_and_confirmed_candidates_are_excluded():
    graph = _graph(2)
    passable = ~OCC
    evidence = np.full(graph.num_variables, -1, dtype=np.int8)
    confirmed = graph.variable(1, 1, "down")
    evidence[confirmed] = 0
    cand = candidate_pushes(graph, travel_distances(passable, ROBOT), evidence)
    dist = grid_distances(passable, ROBOT)
    assert dist[0, 5] < 0 and dist[1, 5] < 0  # the walled-off corner
    assert confirmed not in cand.variables
    for v, (r, c), d, (ar, ac), cost in zip(
        cand.variables, cand.cells, cand.directions, cand.access, cand.costs, strict=True
    ):
        assert graph.variable(int(r), int(c), int(d)) == v
        assert (ar, ac) == (r - DIRECTION_OFFSETS[d][0], c - DIRECTION_OFFSETS[d][1])
        assert passable[ar, ac] and cost == dist[ar, ac] >= 0
    # Pushing (1, 4) left needs the robot at (1, 5), which it cannot reach.
    assert graph.variable(1, 4, "left") not in cand.variables
    # Pushing (0, 4) down needs a cell above row 0: outside the map.
    assert graph.variable(0, 4, "down") not in cand.variables
    # Pushing (2, 1) up needs the robot in (3, 1), reachable.
    assert graph.variable(2, 1, "up") in cand.variables
    # With every free cell blocked except the robot's, nothing is reachable.
    only_here = np.zeros_like(passable)
    only_here[ROBOT] = True
    assert len(candidate_pushes(graph, travel_distances(only_here, ROBOT))) == 0
    # Distances are the planner's only view of the world: -1 everywhere means no candidate.
    assert len(candidate_pushes(graph, np.full((6, 6), -1))) == 0


def test_alpha_is_validated_and_weighs_reward_against_cost():
    graph = _graph(3)
    for bad in (-0.1, 1.5, math.nan, "a"):
        with pytest.raises(InputError, match="alpha"):
            plan_pushes_on_grid(graph, ~OCC, ROBOT, alpha=bad)
        with pytest.raises(InputError, match="alpha"):
            check_alpha(bad)
    only_cost = plan_pushes_on_grid(graph, ~OCC, ROBOT, alpha=0.0)
    assert all(c.gain == -c.cost for c in only_cost.candidates)
    only_reward = plan_pushes_on_grid(graph, ~OCC, ROBOT, alpha=1.0)
    assert all(c.gain == pytest.approx(c.reward) for c in only_reward.candidates)


def test_bad_inputs():
    graph = _graph(4)
    with pytest.raises(InputError, match="passable"):
        plan_pushes_on_grid(graph, np.ones((5, 5), dtype=bool), ROBOT)
    with pytest.raises(InputError, match="robot"):
        plan_pushes_on_grid(graph, ~OCC, (9, 0))
    with pytest.raises(InputError, match="evidence"):
        plan_pushes_on_grid(graph, ~OCC, ROBOT, evidence=np.zeros(3))
    with pytest.raises(InputError, match="distances has shape"):
        plan_pushes(graph, np.zeros((5, 5), dtype=int))
    with pytest.raises(InputError, match="integer path lengths"):
        plan_pushes(graph, np.zeros((6, 6)))


def test_grid_wrapper_matches_the_distance_planner():
    graph = _graph(5)
    on_grid = plan_pushes_on_grid(graph, ~OCC, ROBOT)
    direct = plan_pushes(graph, travel_distances(~OCC, ROBOT))
    assert on_grid.candidates == direct.candidates


def test_a_graph_that_is_not_an_affordance_graph_is_refused():
    dist = travel_distances(~OCC, ROBOT)
    with pytest.raises(InputError, match=r"graph must be an AffordanceGraph .*got ndarray"):
        plan_pushes(OCC, dist)  # type: ignore[arg-type]
    with pytest.raises(InputError, match=r"graph must be an AffordanceGraph .*got str"):
        candidate_pushes("map", dist)  # type: ignore[arg-type]
    with pytest.raises(InputError, match=r"graph must be an AffordanceGraph .*got NoneType"):
        plan_pushes_on_grid(None, ~OCC, ROBOT)  # type: ignore[arg-type]
