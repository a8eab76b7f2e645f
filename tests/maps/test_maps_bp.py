import numpy as np
import pytest
import torch
from maps_helpers import reference_loopy_bp, reference_marginals, shelf_map, sparse_map

from probaff.errors import InputError
from probaff.maps import (
    AffordanceGraph,
    loopy_belief_propagation,
    make_evidence,
    single_variable_evidence,
)
from probaff.maps.bp import ising_form


def _bp(graph, evidence=None, **kw):
    kw.setdefault("dtype", torch.float64)
    kw.setdefault("tol", 1e-13)
    kw.setdefault("max_iterations", 1000)
    return loopy_belief_propagation(
        graph.unary_log_potentials(kw["dtype"]),
        graph.edge_tensor(),
        graph.pairwise_log_potentials(kw["dtype"]),
        evidence,
        **kw,
    )


def _tree_maps():
    rng = np.random.default_rng(11)
    chain = np.ones((1, 12), dtype=bool)
    comb = np.zeros((7, 9), dtype=bool)
    comb[3, :] = True
    comb[:, [0, 4, 8]] = True  # vertical teeth through a horizontal spine: still a forest
    comb[3, [2, 6]] = False
    comb[5, 2:7] = True
    comb[5, [3, 5]] = False
    for occ in (chain, comb):
        yield AffordanceGraph(occ, rng.uniform(0.05, 0.95, (*occ.shape, 4)), coupling=0.4)
    dominoes = np.zeros((5, 5), dtype=bool)  # with symmetry factors only pairs stay trees
    dominoes[0, 0:2] = dominoes[2:4, 0] = dominoes[4, 3:5] = dominoes[1:3, 3] = True
    unary = rng.uniform(0.0, 1.0, (5, 5, 4))
    unary[0, 0, 0], unary[2, 0, 3] = 0.0, 1.0  # deterministic classifier outputs
    yield AffordanceGraph(dominoes, unary, coupling=-2.5, symmetry_coupling=1.5)


def test_bp_is_exact_on_trees():
    worst = 0.0
    for g in _tree_maps():
        assert g.num_edges == g.num_variables - len(g.components)  # a forest
        result = _bp(g)
        assert result.converged
        worst = max(worst, float(np.abs(result.marginals.numpy() - reference_marginals(g)).max()))
    assert worst <= 1e-6


def test_bp_on_sparse_warehouse_maps_matches_gtsam():
    rng = np.random.default_rng(5)
    for _ in range(12):
        occ = sparse_map(rng)
        g = AffordanceGraph(occ, rng.uniform(0.05, 0.95, (12, 12, 4)), coupling=0.4)
        result = _bp(g, dtype=torch.float32, tol=1e-7)
        assert result.converged
        err = np.abs(result.marginals.double().numpy() - reference_marginals(g))[:, 1]
        for variables, edge_ids in zip(g.components, g.component_edge_ids, strict=True):
            tree = edge_ids.size == variables.size - 1
            # exact on trees (up to float32); loopy BP's own approximation error on the
            # rare 2x2 clusters of boxes stays below 1e-2 at J = 0.4
            assert err[variables].max() <= (1e-5 if tree else 1e-2)


def test_bp_on_loopy_shelf_maps_is_the_loopy_fixed_point():
    rng = np.random.default_rng(8)
    for sym in (None, 0.4):
        occ = shelf_map(rng, size=6, lo=8, hi=12)
        g = AffordanceGraph(occ, rng.uniform(0.05, 0.95, (6, 6, 4)), 0.4, sym)
        assert g.num_edges > g.num_variables - len(g.components)  # has cycles
        ours = _bp(g).marginals.numpy()
        ref = reference_loopy_bp(
            np.exp(g.unary_log_potentials(torch.float64).numpy()),
            g.edges,
            np.exp(g.pairwise_log_potentials(torch.float64).numpy()),
        )
        np.testing.assert_allclose(ours, ref, atol=1e-9)
        # and close to, but not exactly, the gtsam marginals
        assert np.abs(ours - reference_marginals(g)).max() < 0.1


def test_batched_evidence_matches_gtsam_with_replaced_unaries():
    rng = np.random.default_rng(2)
    occ = sparse_map(rng)
    g = AffordanceGraph(occ, rng.uniform(0.05, 0.95, (12, 12, 4)), coupling=0.4)
    chosen = [int(c[0]) for c in g.components if c.size > 1][:3]
    rows = [{chosen[0]: 1}, {chosen[0]: 0}, {}, {chosen[1]: 1, chosen[2]: 0}]
    evidence = make_evidence(g.num_variables, rows)
    result = _bp(g, evidence)
    assert result.marginals.shape == (4, g.num_variables, 2)
    trees = np.concatenate(
        [
            c
            for c, ids in zip(g.components, g.component_edge_ids, strict=True)
            if ids.size == c.size - 1
        ]
    )
    for b, clamp in enumerate(rows):
        ref = reference_marginals(g, clamp)
        got = result.marginals[b].numpy()
        np.testing.assert_allclose(got[trees], ref[trees], atol=1e-6)
        np.testing.assert_allclose(got, ref, atol=1e-2)
        for v, value in clamp.items():
            np.testing.assert_array_equal(got[v], [1 - value, value])


def test_single_variable_evidence_batch_equals_separate_runs():
    rng = np.random.default_rng(4)
    occ = shelf_map(rng, size=6, lo=6, hi=9)
    g = AffordanceGraph(occ, rng.uniform(0.05, 0.95, (6, 6, 4)), 0.4, 0.2)
    candidates = [0, 3, g.num_variables - 1]
    evidence = single_variable_evidence(g.num_variables, candidates)
    batched = _bp(g, evidence).marginals
    for row in range(evidence.shape[0]):
        alone = _bp(g, evidence[row]).marginals
        np.testing.assert_allclose(batched[row], alone, atol=1e-10)
    v = candidates[1]
    assert batched[2, v, 1] == 1.0 and batched[3, v, 1] == 0.0


def test_clamping_overrides_an_impossible_unary():
    unary = torch.log(torch.tensor([[1.0, 0.0], [0.5, 0.5]], dtype=torch.float64))
    pairwise = torch.tensor([[[0.4, -0.4], [-0.4, 0.4]]], dtype=torch.float64)
    edges = torch.tensor([[0, 1]])
    free = loopy_belief_propagation(unary, edges, pairwise, dtype=torch.float64).marginals
    np.testing.assert_allclose(free[0], [1.0, 0.0])
    np.testing.assert_allclose(free[1, 1], 1 / (1 + np.exp(0.8)), atol=1e-7)
    clamped = loopy_belief_propagation(
        unary, edges, pairwise, torch.tensor([1, -1]), dtype=torch.float64
    ).marginals
    np.testing.assert_allclose(clamped[0], [0.0, 1.0])
    np.testing.assert_allclose(clamped[1, 1], 1 / (1 + np.exp(-0.8)), atol=1e-7)


def test_ising_form_handles_asymmetric_tables():
    rng = np.random.default_rng(9)
    unary = np.log(rng.uniform(0.1, 1.0, (5, 2)))
    edges = np.array([[0, 1], [1, 2], [1, 3], [3, 4]])
    pairwise = np.log(rng.uniform(0.2, 2.0, (4, 2, 2)))
    result = loopy_belief_propagation(unary, edges, pairwise, dtype=torch.float64, tol=1e-13)
    ref = reference_loopy_bp(np.exp(unary), edges, np.exp(pairwise))  # exact on a tree
    np.testing.assert_allclose(result.marginals.numpy(), ref, atol=1e-10)
    fields, couplings, _ = ising_form(unary, edges, pairwise)
    assert fields.shape == (5,) and couplings.shape == (4,)


def test_result_reports_convergence():
    rng = np.random.default_rng(1)
    g = AffordanceGraph(np.ones((4, 4), bool), rng.uniform(0.05, 0.95, (4, 4, 4)))
    done = _bp(g, tol=1e-8)
    assert done.converged and 1 < done.iterations < 1000 and done.max_delta < 1e-8
    cut = _bp(g, tol=1e-8, max_iterations=2)
    assert not cut.converged and cut.iterations == 2 and cut.max_delta >= 1e-8


def test_float32_default_agrees_with_float64():
    rng = np.random.default_rng(6)
    g = AffordanceGraph(shelf_map(rng), rng.uniform(0.05, 0.95, (12, 12, 4)), 0.4, 0.4)
    single = loopy_belief_propagation(
        g.unary_log_potentials(), g.edge_tensor(), g.pairwise_log_potentials()
    )
    assert single.marginals.dtype == torch.float32 and single.converged
    np.testing.assert_allclose(single.marginals.double(), _bp(g).marginals, atol=1e-5)


def test_graph_without_edges_returns_normalised_unaries():
    unary = torch.log(torch.tensor([[0.2, 0.6], [0.5, 0.5]], dtype=torch.float64))
    r = loopy_belief_propagation(
        unary, torch.zeros(0, 2, dtype=torch.long), torch.zeros(0, 2, 2), dtype=torch.float64
    )
    np.testing.assert_allclose(r.marginals, [[0.25, 0.75], [0.5, 0.5]])
    assert r.converged and r.iterations == 0
    empty = loopy_belief_propagation(
        torch.zeros(0, 2),
        torch.zeros(0, 2, dtype=torch.long),
        torch.zeros(0, 2, 2),
        torch.zeros(3, 0),
    )
    assert empty.marginals.shape == (3, 0, 2)


def _inputs():
    return (
        torch.zeros(3, 2),
        torch.tensor([[0, 1], [1, 2]]),
        torch.tensor([[[0.4, -0.4], [-0.4, 0.4]]] * 2),
    )


def test_evidence_errors():
    unary, edges, pairwise = _inputs()
    with pytest.raises(InputError, match=r"evidence has shape \(2, 4\), expected \(3,\)"):
        loopy_belief_propagation(unary, edges, pairwise, torch.full((2, 4), -1))
    with pytest.raises(InputError, match="-1 \\(free\\), 0 or 1"):
        loopy_belief_propagation(unary, edges, pairwise, torch.tensor([[-1, 2, 0]]))
    with pytest.raises(InputError, match="clamps variable 7, but the model has 3 variables"):
        make_evidence(3, [{0: 1}, {7: 0}])
    with pytest.raises(InputError, match="use 0 or 1"):
        make_evidence(3, [{0: -1}])
    with pytest.raises(InputError, match=r"candidate variables \[3\] do not exist"):
        single_variable_evidence(3, [0, 3])
    with pytest.raises(InputError, match="NaN"):
        loopy_belief_propagation(unary, edges, pairwise, torch.tensor([0.0, np.nan, 1.0]))


def test_potential_and_option_errors():
    unary, edges, pairwise = _inputs()
    with pytest.raises(InputError, match="NaN or \\+inf"):
        loopy_belief_propagation(torch.tensor([[0.0, np.nan]] * 3), edges, pairwise)
    with pytest.raises(InputError, match="both states"):
        loopy_belief_propagation(torch.tensor([[-np.inf, -np.inf]] * 3), edges, pairwise)
    with pytest.raises(InputError, match="outside \\[0, 3\\)"):
        loopy_belief_propagation(unary, torch.tensor([[0, 3], [1, 2]]), pairwise)
    with pytest.raises(InputError, match="self-loops"):
        loopy_belief_propagation(unary, torch.tensor([[1, 1], [1, 2]]), pairwise)
    with pytest.raises(InputError, match="integer"):
        loopy_belief_propagation(unary, edges.double(), pairwise)
    with pytest.raises(InputError, match="pairwise_log has shape"):
        loopy_belief_propagation(unary, edges, pairwise[:1])
    with pytest.raises(InputError, match="NaN"):
        loopy_belief_propagation(unary, edges, pairwise * np.nan)
    with pytest.raises(InputError, match="coupling of 6"):
        loopy_belief_propagation(unary, edges, pairwise * 15)
    with pytest.raises(InputError, match="damping"):
        loopy_belief_propagation(unary, edges, pairwise, damping=1.0)
    with pytest.raises(InputError, match="tol"):
        loopy_belief_propagation(unary, edges, pairwise, tol=-1.0)
    with pytest.raises(InputError, match="max_iterations"):
        loopy_belief_propagation(unary, edges, pairwise, max_iterations=0)
    with pytest.raises(InputError, match="dtype"):
        loopy_belief_propagation(unary, edges, pairwise, dtype=torch.float16)
