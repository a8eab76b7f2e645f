import numpy as np
import pytest
import torch
from maps_helpers import reference_marginals

from probaff.errors import InputError
from probaff.maps import (
    AffordanceGraph,
    affordance_marginals,
    exact_marginals,
    loopy_belief_propagation,
    single_variable_evidence,
)


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
