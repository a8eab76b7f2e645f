import numpy as np
import pytest
import torch
from maps_helpers import reference_marginals

from probaff.errors import InputError
from probaff.maps import (
    AffordanceGraph,
    BPOptions,
    affordance_marginals,
    exact_marginals,
    loopy_belief_propagation,
    single_variable_evidence,
)
from probaff.maps.inference import is_full_grid


def _mixed_map():
    """A fully occupied 9x9 block (too wide for exact) plus a few small clusters."""
    rng = np.random.default_rng(0)
    occ = np.zeros((12, 12), dtype=bool)
    occ[:9, :9] = True
    occ[11, 0:3] = occ[10:12, 10] = True
    return AffordanceGraph(occ, rng.uniform(0.05, 0.95, (12, 12, 4)), coupling=0.4)


def test_auto_uses_exact_on_small_and_bp_on_wide_components():
    g = _mixed_map()
    evidence = single_variable_evidence(g.num_variables, [0, g.num_variables - 1])
    result = affordance_marginals(g, evidence, dtype=torch.float64, tol=1e-13)
    big = {k for k, c in enumerate(g.components) if c.size == 81}
    assert len(big) == 4
    assert all((m == "bp") == (k in big) for k, m in enumerate(result.component_methods))
    assert result.bp is not None and result.bp.converged
    small = [k for k in range(len(g.components)) if k not in big]
    small_vars = np.concatenate([g.components[k] for k in small])
    exact = exact_marginals(g, evidence, components=small)
    np.testing.assert_allclose(result.marginals[:, small_vars], exact[:, small_vars], atol=1e-12)
    bp = loopy_belief_propagation(
        g.unary_log_potentials(torch.float64),
        g.edge_tensor(),
        g.pairwise_log_potentials(torch.float64),
        evidence,
        dtype=torch.float64,
        tol=1e-13,
    )
    big_vars = np.concatenate([g.components[k] for k in big])
    np.testing.assert_allclose(result.marginals[:, big_vars], bp.marginals[:, big_vars], atol=1e-10)


def test_exact_and_bp_methods():
    rng = np.random.default_rng(1)
    occ = np.zeros((5, 5), dtype=bool)
    occ[1:4, 1:3] = True
    g = AffordanceGraph(occ, rng.uniform(0.05, 0.95, (5, 5, 4)), 0.4, 0.2)
    exact = affordance_marginals(g, method="exact", dtype=torch.float64)
    assert exact.bp is None and set(exact.component_methods) == {"exact"}
    np.testing.assert_allclose(exact.marginals, reference_marginals(g), atol=1e-12)
    auto = affordance_marginals(g, dtype=torch.float64)
    np.testing.assert_allclose(auto.marginals, exact.marginals, atol=1e-12)
    bp = affordance_marginals(g, method="bp")
    assert set(bp.component_methods) == {"bp"} and bp.marginals.dtype == torch.float32
    np.testing.assert_allclose(bp.marginals.double(), exact.marginals, atol=2e-2)


def test_method_errors():
    g = _mixed_map()
    with pytest.raises(InputError, match="method must be one of"):
        affordance_marginals(g, method="fast")
    with pytest.raises(InputError, match=r"81 variables.*method='bp'"):
        affordance_marginals(g, method="exact")


def _generic_bp(g, evidence, opts):
    """The edge-list solver on the whole map, in global variable order."""
    return loopy_belief_propagation(
        g.unary_log_potentials(opts.dtype),
        g.edge_tensor(),
        g.pairwise_log_potentials(opts.dtype),
        evidence,
        options=opts,
    )


@pytest.mark.parametrize(
    "shape,along", [((6, 7), None), ((5, 4), -0.3), ((1, 6), None), ((4, 1), 0.0)]
)
def test_full_rectangle_bp_uses_the_grid_solver(shape, along):
    rng = np.random.default_rng(sum(shape))
    g = AffordanceGraph(
        np.ones(shape, dtype=bool),
        rng.uniform(0.05, 0.95, (*shape, 4)),
        coupling=0.4,
        along_coupling=along,
    )
    assert is_full_grid(g)
    evidence = single_variable_evidence(g.num_variables, [0, 5, g.num_variables - 1])
    opts = BPOptions(tol=1e-12, max_iterations=2000, dtype=torch.float64)
    result = affordance_marginals(g, evidence, method="bp", options=opts)
    assert result.bp_solver == "grid" and set(result.component_methods) == {"bp"}
    ref = _generic_bp(g, evidence, opts)
    np.testing.assert_allclose(result.marginals.numpy(), ref.marginals.numpy(), atol=1e-6)
    assert result.bp.converged and result.bp.iterations == ref.iterations
    # The diagnostics hold the BP variables in the generic path's order (components joined).
    order = np.concatenate(g.components)
    np.testing.assert_allclose(result.bp.marginals.numpy(), result.marginals[:, order].numpy())
    # Unbatched evidence gives unbatched marginals; float32 agrees too.
    one = affordance_marginals(g, method="bp")
    assert one.bp_solver == "grid" and one.marginals.shape == (g.num_variables, 2)
    ref32 = _generic_bp(g, None, BPOptions())
    np.testing.assert_allclose(one.marginals.numpy(), ref32.marginals.numpy(), atol=1e-6)


def test_grid_solver_is_not_used_off_the_rectangle():
    rng = np.random.default_rng(3)
    occ = np.ones((4, 4), dtype=bool)
    with_symmetry = AffordanceGraph(occ, rng.uniform(0.1, 0.9, (4, 4, 4)), 0.4, 0.3)
    occ_hole = occ.copy()
    occ_hole[1, 2] = False
    holed = AffordanceGraph(occ_hole, rng.uniform(0.1, 0.9, (4, 4, 4)), 0.4)
    for g in (with_symmetry, holed):
        assert not is_full_grid(g)
        assert affordance_marginals(g, method="bp").bp_solver == "generic"
    full = AffordanceGraph(occ, rng.uniform(0.1, 0.9, (4, 4, 4)))
    assert affordance_marginals(full, method="auto").bp_solver in (None, "generic")
    assert affordance_marginals(full, method="exact").bp_solver is None
