import numpy as np
import pytest
import torch
from maps_helpers import reference_marginals

from probaff.errors import InputError
from probaff.maps import AffordanceGraph, grid_belief_propagation, loopy_belief_propagation


def _grid_edges(height, width):
    ids = np.arange(height * width).reshape(height, width)
    vertical = np.stack([ids[:-1].ravel(), ids[1:].ravel()], axis=1)
    horizontal = np.stack([ids[:, :-1].ravel(), ids[:, 1:].ravel()], axis=1)
    return vertical, horizontal


def test_grid_path_agrees_with_generic_path():
    rng = np.random.default_rng(0)
    height, width = 9, 7
    p = rng.uniform(0.02, 0.98, (height, width))
    unary = torch.log(torch.tensor(np.stack([1 - p, p], axis=-1)))
    j_v = rng.uniform(-1.0, 1.0, (height - 1, width))
    j_h = rng.uniform(-1.0, 1.0, (height, width - 1))
    evidence = torch.full((3, height, width), -1, dtype=torch.int8)
    evidence[1, 4, 3] = 1
    evidence[2, 0, 0], evidence[2, 8, 6] = 0, 1
    grid = grid_belief_propagation(unary, (j_v, j_h), evidence, dtype=torch.float64, tol=1e-13)
    vertical, horizontal = _grid_edges(height, width)
    couplings = np.concatenate([j_v.ravel(), j_h.ravel()])
    signs = np.array([[1.0, -1.0], [-1.0, 1.0]])
    generic = loopy_belief_propagation(
        unary.reshape(-1, 2),
        np.concatenate([vertical, horizontal]),
        couplings[:, None, None] * signs,
        evidence.reshape(3, -1),
        dtype=torch.float64,
        tol=1e-13,
    )
    assert grid.converged and generic.converged
    assert grid.marginals.shape == (3, height, width, 2)
    np.testing.assert_allclose(grid.marginals.reshape(3, -1, 2), generic.marginals, atol=1e-10)


def test_masked_grid_matches_one_direction_of_a_map():
    rng = np.random.default_rng(1)
    occ = rng.random((6, 6)) < 0.6
    g = AffordanceGraph(occ, rng.uniform(0.05, 0.95, (6, 6, 4)), coupling=0.4)
    p = np.where(occ, g.unary[..., 2], 0.5)  # direction "left"
    unary = torch.log(torch.tensor(np.stack([1 - p, p], axis=-1)))
    j_v = np.where(occ[:-1] & occ[1:], 0.4, 0.0)
    j_h = np.where(occ[:, :-1] & occ[:, 1:], 0.4, 0.0)
    grid = grid_belief_propagation(unary, (j_v, j_h), dtype=torch.float64, tol=1e-13)
    ref = reference_marginals(g)
    ours = grid.marginals.numpy()[occ]
    ref_left = ref[g.variable_index[occ][:, 2]]
    np.testing.assert_allclose(ours, ref_left, atol=2e-2)  # loopy approximation
    generic = loopy_belief_propagation(
        g.unary_log_potentials(torch.float64),
        g.edge_tensor(),
        g.pairwise_log_potentials(torch.float64),
        dtype=torch.float64,
        tol=1e-13,
    ).marginals.numpy()
    np.testing.assert_allclose(ours, generic[g.variable_index[occ][:, 2]], atol=1e-10)


def test_float32_grid_and_degenerate_sizes():
    rng = np.random.default_rng(2)
    p = torch.tensor(rng.uniform(0.05, 0.95, (1, 5)), dtype=torch.float32)
    unary = torch.log(torch.stack([1 - p, p], dim=-1))
    row = grid_belief_propagation(unary, 0.4)
    assert row.converged and row.marginals.dtype == torch.float32
    single = grid_belief_propagation(unary[:, :1], 0.4)
    np.testing.assert_allclose(single.marginals[0, 0, 1], p[0, 0], rtol=1e-6)
    assert single.iterations == 0


def test_grid_errors():
    unary = torch.zeros(3, 4, 2)
    with pytest.raises(
        InputError, match=r"vertical coupling has shape \(3, 4\), expected \(2, 4\)"
    ):
        grid_belief_propagation(unary, (np.zeros((3, 4)), np.zeros((3, 3))))
    with pytest.raises(InputError, match="\\|J\\| <= 5"):
        grid_belief_propagation(unary, 7.0)
    with pytest.raises(InputError, match="NaN"):
        grid_belief_propagation(unary, float("nan"))
    with pytest.raises(InputError, match=r"evidence has shape \(4, 3\)"):
        grid_belief_propagation(unary, 0.4, torch.zeros(4, 3))
    with pytest.raises(InputError, match="unary_log has shape"):
        grid_belief_propagation(torch.zeros(3, 4), 0.4)
